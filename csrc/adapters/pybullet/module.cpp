// rblog.adapters._gather: the pybullet adapter's per-step reading of pybullet's Python results
// into arrays (its contact points: contacts.cpp; Bullet's damping: damping.cpp; the bases' states:
// bases.cpp).
#include <nanobind/nanobind.h>

#include "common/errors.hpp"

namespace rb {
void bind_pybullet_contacts(nanobind::module_& m);
void bind_pybullet_damping(nanobind::module_& m);
void bind_pybullet_bases(nanobind::module_& m);
}

NB_MODULE(_gather, m) {
    m.doc() = "rblog's adapters: engine results gathered into arrays (C++, nanobind)";
    rb::register_errors();
    rb::bind_pybullet_contacts(m);
    rb::bind_pybullet_damping(m);
    rb::bind_pybullet_bases(m);
}

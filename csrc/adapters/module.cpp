// rblog.adapters._gather: the adapters' per-step reading of another engine's Python results into
// arrays (pybullet's contact points: pybullet_contacts.cpp; Bullet's damping: pybullet_damping.cpp).
#include <nanobind/nanobind.h>

#include "common/errors.hpp"

namespace rb {
void bind_pybullet_contacts(nanobind::module_& m);
void bind_pybullet_damping(nanobind::module_& m);
}

NB_MODULE(_gather, m) {
    m.doc() = "rblog's adapters: engine results gathered into arrays (C++, nanobind)";
    rb::register_errors();
    rb::bind_pybullet_contacts(m);
    rb::bind_pybullet_damping(m);
}

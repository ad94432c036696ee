// rblog.engine._core: the engine's per-step code (docs/architecture.md, "C++ and Python").
#include "common/errors.hpp"
#include "engine/bind.hpp"

NB_MODULE(_core, m) {
    m.doc() = "rblog's engine core: free-body kernels and the contact step (C++, nanobind)";
    rb::register_errors();
    rb::bind_threads(m);
    rb::bind_free(m);
    rb::bind_collision(m);
    rb::bind_contact(m);
}

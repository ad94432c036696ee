// rblog.contract._derive: the log contract's derived channels (derive.cpp) and the state a
// writer's velocities imply (state.cpp). A module of its own
// because the contract imports nothing else of rblog (docs/architecture.md): not the engine's
// core, not the recorders' encoder.
#include <nanobind/nanobind.h>

namespace rb {
void bind_derive(nanobind::module_& m);
void bind_state(nanobind::module_& m);
}

NB_MODULE(_derive, m) {
    m.doc() = "rblog's log contract: the derived channels (C++, nanobind)";
    rb::bind_derive(m);
    rb::bind_state(m);
}

// Bindings of the contact step and its stages (world_step.cpp and the stage files).
#include "engine/bind.hpp"

namespace rb {
void bind_contact(nanobind::module_& m) { (void)m; }
}  // namespace rb

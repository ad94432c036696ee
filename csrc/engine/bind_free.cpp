// Bindings of the free-body kernels (free.cpp).
#include "engine/bind.hpp"

namespace rb {
void bind_free(nanobind::module_& m) { (void)m; }
}  // namespace rb

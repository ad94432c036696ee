// Bindings of the encoders.
#include <nanobind/nanobind.h>

namespace rb {
void bind_encode(nanobind::module_& m) { (void)m; }
}  // namespace rb

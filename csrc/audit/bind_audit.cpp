// Bindings of the audit kernels.
#include <nanobind/nanobind.h>

namespace rb {
void bind_audit(nanobind::module_& m) { (void)m; }
}  // namespace rb

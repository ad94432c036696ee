// Bindings of the encoders: the MCAP message encoder (mcap_encode.cpp).
#include <nanobind/nanobind.h>

namespace rb {
void bind_mcap_encode(nanobind::module_& m);

void bind_encode(nanobind::module_& m) { bind_mcap_encode(m); }
}  // namespace rb

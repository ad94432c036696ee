// Bindings of the encoders: the MCAP message encoder (mcap_encode.cpp) and the chunks' CRC-32
// (crc32.cpp).
#include <nanobind/nanobind.h>

namespace rb {
void bind_mcap_encode(nanobind::module_& m);
void bind_crc32(nanobind::module_& m);

void bind_encode(nanobind::module_& m) {
    bind_mcap_encode(m);
    bind_crc32(m);
}
}  // namespace rb

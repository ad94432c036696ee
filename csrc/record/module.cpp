// rblog.record._encode: the MCAP message encoder (the derived channels are the contract's:
// rblog.contract._derive, csrc/contract/).
#include <nanobind/nanobind.h>

#include "common/errors.hpp"

namespace rb {
void bind_encode(nanobind::module_& m);
}

NB_MODULE(_encode, m) {
    m.doc() = "rblog's MCAP message encoder (C++, nanobind)";
    rb::register_errors();
    rb::bind_encode(m);
}

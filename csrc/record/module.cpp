// rblog.record._encode: the derived channels of the log contract and the MCAP message encoder.
#include <nanobind/nanobind.h>

#include "common/errors.hpp"

namespace rb {
void bind_encode(nanobind::module_& m);
}

NB_MODULE(_encode, m) {
    m.doc() = "rblog's log encoders and derived channels (C++, nanobind)";
    rb::register_errors();
    rb::bind_encode(m);
}

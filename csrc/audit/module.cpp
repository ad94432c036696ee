// rblog.analyze._audit: the analyzers' compiled kernels. Written apart from the engine's
// (csrc/engine/): an audit that shared the code it audits would inherit its bugs.
#include <nanobind/nanobind.h>

#include "common/errors.hpp"

namespace rb {
void bind_audit(nanobind::module_& m);
}

NB_MODULE(_audit, m) {
    m.doc() = "rblog's audit kernels (C++, nanobind); apart from the engine's code";
    rb::register_errors();
    rb::bind_audit(m);
}

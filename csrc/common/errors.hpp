// Errors the core raises, as rblog's own exceptions (rblog/errors.py): a C++ stage throws
// rb::Error("SceneError", "what went wrong"), Python sees rblog.errors.SceneError("what went
// wrong"). A diverging body is not an error here: the stepping calls return it (step and body)
// and the run loop raises SimulationDiverged with the body's name.
#pragma once

#include <nanobind/nanobind.h>

#include <stdexcept>
#include <string>

namespace rb {

struct Error : std::runtime_error {
    std::string py_class;  // a class name of rblog.errors
    Error(std::string cls, const std::string& what) : std::runtime_error(what), py_class(std::move(cls)) {}
};

// Installs the translator (once per module, at import).
inline void register_errors() {
    nanobind::register_exception_translator([](const std::exception_ptr& p, void*) {
        try {
            std::rethrow_exception(p);
        } catch (const Error& e) {
            nanobind::object errors = nanobind::module_::import_("rblog.errors");
            nanobind::object cls = errors.attr(e.py_class.c_str());
            PyErr_SetString(cls.ptr(), e.what());
        }
    });
}

}  // namespace rb

// The pybullet adapter's state read (Stepper.read in rblog/adapters/pybullet.py) for a world of
// bases alone (no links): for each body, pybullet's getBasePositionAndOrientation and
// getBaseVelocity called from here, their numbers written straight into the rows' arrays (the
// same doubles as the Python read: position, orientation xyzw, linear and angular velocity).
#include <nanobind/nanobind.h>

#include <string>

#include "common/py.hpp"

namespace rb {
namespace nb = nanobind;

namespace {

// the k-th of `n` numbers of pybullet's result `r` (a tuple of tuples): r[outer][inner]
void put(PyObject* r, Py_ssize_t outer, Py_ssize_t n, double* out, const char* what, long body) {
    if (!PyTuple_Check(r) || PyTuple_GET_SIZE(r) <= outer)
        throw nb::type_error((std::string(what) + " of body " + std::to_string(body) +
                              ": expected pybullet's tuple").c_str());
    PyObject* t = PyTuple_GET_ITEM(r, outer);
    if (!PyTuple_Check(t) || PyTuple_GET_SIZE(t) != n)
        throw nb::type_error((std::string(what) + " of body " + std::to_string(body) +
                              ": expected a tuple of " + std::to_string(n) + " numbers").c_str());
    for (Py_ssize_t i = 0; i < n; ++i) {
        double v = PyFloat_AsDouble(PyTuple_GET_ITEM(t, i));
        if (v == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            throw nb::type_error((std::string(what) + " of body " + std::to_string(body) +
                                  ": expected numbers").c_str());
        }
        out[i] = v;
    }
}

void read_bases(nb::handle get_pose, nb::handle get_velocity, nb::handle bodies_h, nb::handle kw,
                nb::handle x_h, nb::handle q_h, nb::handle v_h, nb::handle w_h) {
    V1<i64> bodies = v1<i64>(bodies_h, "bodies");
    V2<double> x = v2<double>(x_h, "x"), q = v2<double>(q_h, "q"), v = v2<double>(v_h, "v"),
               w = v2<double>(w_h, "w");
    const i64 n = bodies.n0;
    if (x.n0 != n || x.n1 != 3 || q.n0 != n || q.n1 != 4 || v.n0 != n || v.n1 != 3 ||
        w.n0 != n || w.n1 != 3)
        throw nb::value_error("read_bases: x, v, w (N, 3), q (N, 4) for N bodies");
    for (i64 i = 0; i < n; ++i) {
        nb::object id = nb::int_(bodies(i));
        nb::tuple args = nb::make_tuple(id);
        nb::object pose = nb::steal(PyObject_Call(get_pose.ptr(), args.ptr(), kw.ptr()));
        if (!pose.is_valid()) throw nb::python_error();
        nb::object vel = nb::steal(PyObject_Call(get_velocity.ptr(), args.ptr(), kw.ptr()));
        if (!vel.is_valid()) throw nb::python_error();
        put(pose.ptr(), 0, 3, &x(i, 0), "getBasePositionAndOrientation", (long)bodies(i));
        put(pose.ptr(), 1, 4, &q(i, 0), "getBasePositionAndOrientation", (long)bodies(i));
        put(vel.ptr(), 0, 3, &v(i, 0), "getBaseVelocity", (long)bodies(i));
        put(vel.ptr(), 1, 3, &w(i, 0), "getBaseVelocity", (long)bodies(i));
    }
}

}  // namespace

void bind_pybullet_bases(nb::module_& m) {
    m.def("pybullet_read_bases", &read_bases,
          "pybullet_read_bases(getBasePositionAndOrientation, getBaseVelocity, bodies, kwargs, "
          "x, q, v, w): each body's base state into the rows (csrc/adapters/pybullet/bases.cpp)");
}

}  // namespace rb

// pybullet's getContactPoints() -> arrays, without a Python object per number.
//
// A point is pybullet's 14-tuple (contactFlag, bodyUniqueIdA, bodyUniqueIdB, linkIndexA,
// linkIndexB, positionOnA (3), positionOnB (3), contactNormalOnB (3), contactDistance,
// normalForce, lateralFriction1, lateralFrictionDir1 (3), lateralFriction2,
// lateralFrictionDir2 (3)). The force on A is F = normalForce n + lateralFriction1 d1 +
// lateralFriction2 d2 (N, world frame); B receives -F. Bullet applies the impulse F dt at
// positionOnA on A and at positionOnB on B, about each link's centre of mass at the start of the
// step (the solver's lever arms).
#include <nanobind/nanobind.h>

#include <string>

#include "common/py.hpp"

namespace rb {
namespace nb = nanobind;

namespace {

PyObject* point_at(PyObject* pts, Py_ssize_t i) {
    PyObject* p = PySequence_Fast_GET_ITEM(pts, i);
    if (!PyTuple_Check(p) || PyTuple_GET_SIZE(p) != 14)
        throw nb::type_error(("contact point " + std::to_string(i) +
                              ": expected pybullet's 14-tuple").c_str());
    return p;
}

double num(PyObject* p, Py_ssize_t k, Py_ssize_t i) {
    double v = PyFloat_AsDouble(PyTuple_GET_ITEM(p, k));
    if (v == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        throw nb::type_error(("contact point " + std::to_string(i) + ", field " +
                              std::to_string(k) + ": expected a number").c_str());
    }
    return v;
}

void vec(PyObject* p, Py_ssize_t k, Py_ssize_t i, double* out) {
    PyObject* t = PyTuple_GET_ITEM(p, k);
    if (!PyTuple_Check(t) || PyTuple_GET_SIZE(t) != 3)
        throw nb::type_error(("contact point " + std::to_string(i) + ", field " +
                              std::to_string(k) + ": expected a 3-tuple").c_str());
    for (int c = 0; c < 3; ++c) {
        out[c] = PyFloat_AsDouble(PyTuple_GET_ITEM(t, c));
        if (out[c] == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            throw nb::type_error(("contact point " + std::to_string(i) + ", field " +
                                  std::to_string(k) + ": expected numbers").c_str());
        }
    }
}

struct Seq {  // a tuple or list, held for the call
    PyObject* fast;
    explicit Seq(nb::handle h) : fast(PySequence_Fast(h.ptr(), "points: expected a sequence")) {
        if (!fast) throw nb::python_error();
    }
    ~Seq() { Py_XDECREF(fast); }
    Py_ssize_t size() const { return PySequence_Fast_GET_SIZE(fast); }
};

i64 row_of(const V2<i64>& table, i64 body, i64 link) {
    if (body < 0 || body >= table.n0 || link + 1 < 0 || link + 1 >= table.n1) return -1;
    return table(body, link + 1);
}

}  // namespace

// Adds every point's impulse into lin, ang (N, 3). With rows_out (P, 14) given (not None), the
// same pass writes the contract's contact rows and returns how many; else -1.
// The contract's contact rows (accumulate's rows_out, P x 14): body_a, body_b (rows; -1 =
// static geometry), point (3, the midpoint of positionOnA and positionOnB), normal (3, from B
// into A), separation (contactDistance), normal impulse, 0, friction impulse (3, on A), all
// N s = force x dt. A point whose A is not recorded is swapped (B becomes body_a, the normal and
// friction flip); points with neither recorded, and speculative ones (no normal force, positive
// distance), get no row.
static i64 accumulate(nb::handle points, nb::handle row_table, nb::handle x0_h, double dt,
                      nb::handle lin_h, nb::handle ang_h, nb::handle rows_out) {
    V2<i64> table = v2<i64>(row_table, "row_of");
    V2<double> x0 = v2<double>(x0_h, "x0");
    V2<double> lin = v2<double>(lin_h, "lin");
    V2<double> ang = v2<double>(ang_h, "ang");
    if (x0.n1 != 3 || lin.n0 != x0.n0 || lin.n1 != 3 || ang.n0 != x0.n0 || ang.n1 != 3)
        throw nb::type_error("accumulate: x0, lin, ang must be (N, 3) alike");
    Seq pts(points);
    const Py_ssize_t n = pts.size();
    const bool with_rows = !rows_out.is_none();
    V2<double> out;
    if (with_rows) {
        out = v2<double>(rows_out, "rows_out");
        if (out.n0 < n || out.n1 != 14)
            throw nb::type_error(("rows_out must be (>= " + std::to_string(n) + ", 14)").c_str());
    }
    i64 k = 0;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject* p = point_at(pts.fast, i);
        const i64 a = row_of(table, (i64)num(p, 1, i), (i64)num(p, 3, i));
        const i64 b = row_of(table, (i64)num(p, 2, i), (i64)num(p, 4, i));
        if (a < 0 && b < 0) continue;
        double pa[3], pb[3], nrm[3], d1[3], d2[3], f[3];
        vec(p, 5, i, pa);
        vec(p, 6, i, pb);
        vec(p, 7, i, nrm);
        vec(p, 11, i, d1);
        vec(p, 13, i, d2);
        const double fn = num(p, 9, i), f1 = num(p, 10, i), f2 = num(p, 12, i);
        for (int c = 0; c < 3; ++c) f[c] = (fn * nrm[c] + f1 * d1[c] + f2 * d2[c]) * dt;
        if (a >= 0) {
            const double r[3] = {pa[0] - x0(a, 0), pa[1] - x0(a, 1), pa[2] - x0(a, 2)};
            for (int c = 0; c < 3; ++c) lin(a, c) += f[c];
            ang(a, 0) += r[1] * f[2] - r[2] * f[1];
            ang(a, 1) += r[2] * f[0] - r[0] * f[2];
            ang(a, 2) += r[0] * f[1] - r[1] * f[0];
        }
        if (b >= 0) {
            const double r[3] = {pb[0] - x0(b, 0), pb[1] - x0(b, 1), pb[2] - x0(b, 2)};
            for (int c = 0; c < 3; ++c) lin(b, c) -= f[c];
            ang(b, 0) -= r[1] * f[2] - r[2] * f[1];
            ang(b, 1) -= r[2] * f[0] - r[0] * f[2];
            ang(b, 2) -= r[0] * f[1] - r[1] * f[0];
        }
        if (with_rows) {
            const double dist = num(p, 8, i);
            if (fn <= 0.0 && dist > 0.0) continue;  // speculative
            const double s = a >= 0 ? 1.0 : -1.0;  // B becomes body_a: normal and friction flip
            double* r = out.row(k++);
            r[0] = (double)(a >= 0 ? a : b);
            r[1] = (double)(a >= 0 ? b : -1);
            for (int c = 0; c < 3; ++c) {
                r[2 + c] = 0.5 * (pa[c] + pb[c]);
                r[5 + c] = s * nrm[c];
                r[11 + c] = s * (f1 * d1[c] + f2 * d2[c]) * dt;
            }
            r[8] = dist;
            r[9] = fn * dt;
            r[10] = 0.0;
        }
    }
    return with_rows ? k : -1;
}

void bind_pybullet_contacts(nb::module_& m) {
    m.def("pybullet_contacts_accumulate", &accumulate, nb::arg("points"), nb::arg("row_of"),
          nb::arg("x0"), nb::arg("dt"), nb::arg("lin"), nb::arg("ang"),
          nb::arg("rows_out").none() = nb::none(),
          "Add each getContactPoints() point's impulse (N s) and its moment about the row's "
          "centre of mass x0 (N m s) into lin, ang (N, 3); row_of (B, W) int64 maps (body, "
          "link + 1) to a row, -1 = not recorded. With rows_out (P, 14) float64, also the "
          "contract's contact rows: returns their number (else -1).");
}

}  // namespace rb

// From Python objects to views (array.hpp), and back: the one place where numpy arrays cross
// into C++. Arrays are taken as they are, never converted: a float32 or non-contiguous array where
// the core writes in place would otherwise be copied and the write lost, so a wrong dtype, shape
// or layout is a TypeError that names the argument.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "common/array.hpp"

namespace rb {
namespace nb = nanobind;

template <class T>
const char* dtype_name() {
    if constexpr (std::is_same_v<T, double>) return "float64";
    else if constexpr (std::is_same_v<T, float>) return "float32";
    else if constexpr (std::is_same_v<T, std::int64_t>) return "int64";
    else if constexpr (std::is_same_v<T, std::int32_t>) return "int32";
    else if constexpr (std::is_same_v<T, std::uint8_t>) return "uint8";
    else if constexpr (std::is_same_v<T, bool>) return "bool";
    else return "?";
}

template <class T>
using CArr = nb::ndarray<T, nb::c_contig, nb::device::cpu>;

template <class T>
CArr<T> as_array(nb::handle h, const char* name, size_t ndim) {
    CArr<T> a;
    if (!nb::try_cast(h, a, false) || a.ndim() != ndim) {
        std::string got = nb::cast<std::string>(nb::str(nb::getattr(h, "dtype", nb::none())));
        std::string shape = nb::cast<std::string>(nb::str(nb::getattr(h, "shape", nb::none())));
        throw nb::type_error((std::string(name) + ": expected a C-contiguous " +
                              dtype_name<T>() + " array of " + std::to_string(ndim) +
                              " dimensions, got dtype " + got + ", shape " + shape)
                                 .c_str());
    }
    return a;
}

template <class T> V1<T> v1(nb::handle h, const char* name) {
    auto a = as_array<T>(h, name, 1);
    return V1<T>{a.data(), (i64)a.shape(0)};
}
template <class T> V2<T> v2(nb::handle h, const char* name) {
    auto a = as_array<T>(h, name, 2);
    return V2<T>{a.data(), (i64)a.shape(0), (i64)a.shape(1)};
}
template <class T> V3<T> v3(nb::handle h, const char* name) {
    auto a = as_array<T>(h, name, 3);
    return V3<T>{a.data(), (i64)a.shape(0), (i64)a.shape(1), (i64)a.shape(2)};
}
template <class T> V4<T> v4(nb::handle h, const char* name) {
    auto a = as_array<T>(h, name, 4);
    return V4<T>{a.data(), (i64)a.shape(0), (i64)a.shape(1), (i64)a.shape(2), (i64)a.shape(3)};
}

// A field of a record (a namedtuple or any object with attributes) as a view.
template <class T> V1<T> f1(nb::handle rec, const char* attr) { return v1<T>(rec.attr(attr), attr); }
template <class T> V2<T> f2(nb::handle rec, const char* attr) { return v2<T>(rec.attr(attr), attr); }
template <class T> V3<T> f3(nb::handle rec, const char* attr) { return v3<T>(rec.attr(attr), attr); }
template <class T> V4<T> f4(nb::handle rec, const char* attr) { return v4<T>(rec.attr(attr), attr); }
template <class T> T scalar(nb::handle rec, const char* attr) { return nb::cast<T>(rec.attr(attr)); }

// A new numpy array that takes over a std::vector's buffer (no copy); `shape` in C order.
template <class T>
nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& v, std::initializer_list<size_t> shape) {
    auto* owned = new std::vector<T>(std::move(v));
    nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    return nb::ndarray<nb::numpy, T>(owned->data(), shape.size(), shape.begin(), owner);
}

// The first `rows` rows of a C++-owned 2-D buffer, copied into a new numpy array.
template <class T>
nb::ndarray<nb::numpy, T> rows_to_numpy(const Buf2<T>& b, i64 rows) {
    std::vector<T> out(b.data.begin(), b.data.begin() + rows * b.cols);
    return to_numpy<T>(std::move(out), {(size_t)rows, (size_t)b.cols});
}

}  // namespace rb

// Views over numpy buffers: a pointer and a shape, C order (row-major, last index fastest).
//
// The engine's records are struct-of-arrays over bodies, float64 (or int64 codes), bodies first,
// exactly the numpy arrays Python holds (rblog/engine/contact/step.py names them): a view shares
// the memory, nothing is copied in or out. A view does not own its buffer; the Python object that
// does outlives the call that uses the view.
#pragma once

#include <cstdint>
#include <vector>

namespace rb {

using i64 = std::int64_t;

template <class T>
struct V1 {
    T* p = nullptr;
    i64 n0 = 0;
    T& operator[](i64 i) const { return p[i]; }
    T& operator()(i64 i) const { return p[i]; }
    i64 size() const { return n0; }
};

template <class T>
struct V2 {
    T* p = nullptr;
    i64 n0 = 0, n1 = 0;
    T& operator()(i64 i, i64 j) const { return p[i * n1 + j]; }
    T* row(i64 i) const { return p + i * n1; }
};

template <class T>
struct V3 {
    T* p = nullptr;
    i64 n0 = 0, n1 = 0, n2 = 0;
    T& operator()(i64 i, i64 j, i64 k) const { return p[(i * n1 + j) * n2 + k]; }
    T* row(i64 i) const { return p + i * n1 * n2; }
};

template <class T>
struct V4 {
    T* p = nullptr;
    i64 n0 = 0, n1 = 0, n2 = 0, n3 = 0;
    T& operator()(i64 i, i64 j, i64 k, i64 l) const {
        return p[((i * n1 + j) * n2 + k) * n3 + l];
    }
};

// A growable 2-D buffer owned by C++ (manifolds, points, contact rows): rows of `cols` values.
// grow() keeps the contents; views taken before a grow() are stale after it.
template <class T>
struct Buf2 {
    std::vector<T> data;
    i64 rows = 0, cols = 0;
    Buf2() = default;
    Buf2(i64 r, i64 c) : data(static_cast<size_t>(r * c), T(0)), rows(r), cols(c) {}
    void grow(i64 need) {  // at least `need` rows; doubles so growth is amortised O(1)
        if (need <= rows) return;
        i64 cap = need > 2 * rows ? need : 2 * rows;
        data.resize(static_cast<size_t>(cap * cols), T(0));
        rows = cap;
    }
    V2<T> view() { return V2<T>{data.data(), rows, cols}; }
    T& operator()(i64 i, i64 j) { return data[static_cast<size_t>(i * cols + j)]; }
};

}  // namespace rb

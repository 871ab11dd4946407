// Small dense types shared by every layer of the compiled engine.
//
// Row-major, like NumPy's C order, so a view can sit on a NumPy array without a copy.
// No expression templates and no BLAS: the kernels are plain loops over small matrices
// (IK sizes, n <= ~100), written in the same order as the Python reference so that the
// same inputs give the same bits (the build uses -ffp-contract=off and no -ffast-math).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace qpik {

using i64 = std::int64_t;
using i8 = std::int8_t;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A row-major view on doubles owned elsewhere (a NumPy array or a Mat).
template <class T>
struct MatRefT {
    T* p = nullptr;
    i64 rows = 0;
    i64 cols = 0;
    i64 stride = 0;  // elements between two rows

    MatRefT() = default;
    MatRefT(T* data, i64 r, i64 c) : p(data), rows(r), cols(c), stride(c) {}
    MatRefT(T* data, i64 r, i64 c, i64 s) : p(data), rows(r), cols(c), stride(s) {}
    template <class U>
    MatRefT(const MatRefT<U>& o) : p(o.p), rows(o.rows), cols(o.cols), stride(o.stride) {}

    T& operator()(i64 i, i64 j) const { return p[i * stride + j]; }
    T* row(i64 i) const { return p + i * stride; }
    // Rows r0:r1 (a view).
    MatRefT rows_slice(i64 r0, i64 r1) const { return MatRefT(p + r0 * stride, r1 - r0, cols, stride); }
};
using MatRef = MatRefT<double>;
using CMatRef = MatRefT<const double>;

// A view on a contiguous vector.
template <class T>
struct VecRefT {
    T* p = nullptr;
    i64 n = 0;
    VecRefT() = default;
    VecRefT(T* data, i64 size) : p(data), n(size) {}
    template <class U>
    VecRefT(const VecRefT<U>& o) : p(o.p), n(o.n) {}
    template <class U>
    VecRefT(std::vector<U>& v) : p(v.data()), n(static_cast<i64>(v.size())) {}
    template <class U>
    VecRefT(const std::vector<U>& v) : p(v.data()), n(static_cast<i64>(v.size())) {}
    T& operator[](i64 i) const { return p[i]; }
    i64 size() const { return n; }
    T* begin() const { return p; }
    T* end() const { return p + n; }
    VecRefT slice(i64 a, i64 b) const { return VecRefT(p + a, b - a); }
};
using VecRef = VecRefT<double>;
using CVecRef = VecRefT<const double>;

// An owning row-major matrix.
struct Mat {
    i64 rows = 0;
    i64 cols = 0;
    std::vector<double> a;

    Mat() = default;
    Mat(i64 r, i64 c, double fill = 0.0) : rows(r), cols(c), a(static_cast<size_t>(r * c), fill) {}
    static Mat eye(i64 n) {
        Mat m(n, n);
        for (i64 i = 0; i < n; ++i) m(i, i) = 1.0;
        return m;
    }
    // Reshaped to (r, c) and filled with zeros, the storage kept (no allocation unless it
    // grows): the same contents as Mat(r, c) in its r c entries (a may hold more past them,
    // as shape leaves it; never shrunk, so that sizes that alternate call no resize).
    void zeros(i64 r, i64 c);
    // The identity of order n, the storage kept: the same contents as Mat::eye(n).
    void set_eye(i64 n) {
        zeros(n, n);
        for (i64 i = 0; i < n; ++i) (*this)(i, i) = 1.0;
    }
    double& operator()(i64 i, i64 j) { return a[static_cast<size_t>(i * cols + j)]; }
    double operator()(i64 i, i64 j) const { return a[static_cast<size_t>(i * cols + j)]; }
    double* row(i64 i) { return a.data() + i * cols; }
    const double* row(i64 i) const { return a.data() + i * cols; }
    MatRef ref() { return MatRef(a.data(), rows, cols); }
    CMatRef ref() const { return CMatRef(a.data(), rows, cols); }
    CMatRef cref() const { return CMatRef(a.data(), rows, cols); }
};

using Vec = std::vector<double>;

// p[0..n) = +0.0 by 16-byte stores, eight entries a pass (no memset call: glibc's memset of
// a few kB runs rep stosb, which callgrind counts by the iteration, and a call either way; the
// loop is 7 instructions per 8 entries). The loop is kept from becoming a memset call by
// the empty asm (GCC recognises a zeroing loop at -O2 otherwise).
inline void zero_many(double* p, size_t n) {
    typedef double v2d_ __attribute__((vector_size(16)));
    const v2d_ z = {0.0, 0.0};
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        std::memcpy(p + i, &z, sizeof z);
        std::memcpy(p + i + 2, &z, sizeof z);
        std::memcpy(p + i + 4, &z, sizeof z);
        std::memcpy(p + i + 6, &z, sizeof z);
        __asm__ volatile("" ::: "memory");
    }
    for (; i + 2 <= n; i += 2) std::memcpy(p + i, &z, sizeof z);
    if (i < n) p[i] = 0.0;
}

// v of size n, every entry +0.0: the contents of v.assign(n, 0.0) (+0.0 is the all-zero bit
// pattern), written by 16-byte stores (the element loop of assign is ~3 instructions an entry).
// Growing, only the entries v already had are cleared: resize value-initialises the rest.
// Up to 8 entries are stored one by one (no call: the sizes of IK's small levels), more by
// zero_many.
inline void zero_small(double* p, size_t n) {
    switch (n) {
        case 8: p[7] = 0.0; [[fallthrough]];
        case 7: p[6] = 0.0; [[fallthrough]];
        case 6: p[5] = 0.0; [[fallthrough]];
        case 5: p[4] = 0.0; [[fallthrough]];
        case 4: p[3] = 0.0; [[fallthrough]];
        case 3: p[2] = 0.0; [[fallthrough]];
        case 2: p[1] = 0.0; [[fallthrough]];
        case 1: p[0] = 0.0; [[fallthrough]];
        case 0: return;
        default: zero_many(p, n);
    }
}

inline void zero_fill(Vec& v, size_t n) {
    const size_t old = v.size();
    if (n <= old) {
        if (n < old) v.resize(n);  // shrinking: no call, no allocation
        zero_small(v.data(), n);
        return;
    }
    zero_small(v.data(), old);
    v.resize(n);
}

// v's first n entries +0.0, its size at least n (grown, never shrunk: for scratch read only
// through its first n entries, so that sizes that alternate call no resize).
inline void zero_prefix(Vec& v, size_t n) {
    const size_t old = v.size();
    if (old < n) {  // growing: the entries it had cleared, resize value-initialises the rest
        zero_small(v.data(), old);
        v.resize(n);
        return;
    }
    zero_small(v.data(), n);
}

inline void Mat::zeros(i64 r, i64 c) {
    rows = r;
    cols = c;
    zero_prefix(a, static_cast<size_t>(r * c));
}
using IVec = std::vector<i64>;
using BVec = std::vector<i8>;

// Thrown for arguments the Python layer should have rejected; arrives as ValueError.
struct BadArgument : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

}  // namespace qpik

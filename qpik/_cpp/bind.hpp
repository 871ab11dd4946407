// Conversions between NumPy arrays and the engine's views, with the checks that keep a
// bad argument from reaching the kernels (a wrong shape, dtype or layout raises
// ValueError in Python instead of reading out of bounds).
//
// Inputs are taken as `In2`/`In1` (read-only; NumPy converts other dtypes or layouts
// with a copy). Arrays the kernels write into are `Out2`/`Out1`, bound with
// `.noconvert()` so that a conversion can never silently write into a temporary copy.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/tuple.h>

#include <cstring>
#include <utility>

#include "common.hpp"

namespace qpik::bind {

namespace nb = nanobind;

template <class T, size_t D>
using In = nb::ndarray<const T, nb::numpy, nb::ndim<D>, nb::c_contig, nb::device::cpu>;
template <class T, size_t D>
using Out = nb::ndarray<T, nb::numpy, nb::ndim<D>, nb::c_contig, nb::device::cpu>;
using In1 = In<double, 1>;
using In2 = In<double, 2>;
using In3 = In<double, 3>;
using Out1 = Out<double, 1>;
using Out2 = Out<double, 2>;
using Out3 = Out<double, 3>;

template <class A>
inline CMatRef cmat(const A& x) {
    return CMatRef(x.data(), static_cast<i64>(x.shape(0)), static_cast<i64>(x.shape(1)));
}
template <class A>
inline MatRef mat(A& x) {
    return MatRef(x.data(), static_cast<i64>(x.shape(0)), static_cast<i64>(x.shape(1)));
}
template <class A>
inline CVecRef cvec(const A& x) {
    return CVecRef(x.data(), static_cast<i64>(x.shape(0)));
}
template <class A>
inline VecRef vec(A& x) {
    return VecRef(x.data(), static_cast<i64>(x.shape(0)));
}

inline void require(bool ok, const char* what) {
    if (!ok) throw BadArgument(what);
}

// A new NumPy array that owns a moved-in std::vector (no copy of the data).
template <class T>
inline nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& v, std::initializer_list<size_t> shape) {
    auto* heap = new std::vector<T>(std::move(v));
    nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    return nb::ndarray<nb::numpy, T>(heap->data(), shape, owner);
}
template <class T>
inline nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& v) {
    size_t n = v.size();
    return to_numpy(std::move(v), {n});
}
inline nb::ndarray<nb::numpy, double> to_numpy(Mat&& m) {
    size_t r = static_cast<size_t>(m.rows), c = static_cast<size_t>(m.cols);
    return to_numpy(std::move(m.a), {r, c});
}

}  // namespace qpik::bind

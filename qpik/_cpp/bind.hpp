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

#include <cstdint>
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

namespace qpik::bind {

// NumPy arrays read without the buffer protocol (PyObject_GetBuffer costs about 600
// instructions a call, a large share of a small solve's overhead): the leading fields of
// NumPy's PyArrayObject_fields and PyArray_Descr (the same offsets in NumPy 1.x and 2.x),
// mirrored here and checked once against the buffer protocol on arrays made for the check
// (float64 2-D, its transpose, a read-only and an int8 array). When any check fails the
// fast path is off and every read takes the buffer protocol, as before. Only an exact
// numpy.ndarray (not a subclass), aligned, of the item type asked for, native byte order.
namespace npy_detail {
struct ArrayFields {
    PyObject_HEAD
    char* data;
    int nd;
    Py_ssize_t* dimensions;
    Py_ssize_t* strides;
    PyObject* base;
    PyObject* descr;
    int flags;
};
struct DescrFields {
    PyObject_HEAD
    PyTypeObject* typeobj;
    char kind;
    char type;
    char byteorder;
    char former_flags;
    int type_num;
};
constexpr int kCContiguous = 0x0001, kAligned = 0x0100, kWriteable = 0x0400;
constexpr unsigned kWarnOnWrite = 1u << 31;

inline bool little_endian() {
    const uint16_t one = 1;
    unsigned char c;
    std::memcpy(&c, &one, 1);
    return c == 1;
}

// The fields of `o` agree with what the buffer protocol reports (Python error cleared).
inline bool agrees(PyObject* o, char type, int type_num, bool c_contig, bool writable) {
    Py_buffer v;
    if (PyObject_GetBuffer(o, &v, PyBUF_STRIDES | PyBUF_FORMAT) != 0) {
        PyErr_Clear();
        return false;
    }
    const auto* a = reinterpret_cast<const ArrayFields*>(o);
    const auto* d = reinterpret_cast<const DescrFields*>(a->descr);
    bool ok = a->data == v.buf && a->nd == v.ndim && d != nullptr && d->type == type &&
              d->type_num == type_num && d->byteorder != '>' && (a->flags & kAligned) != 0 &&
              ((a->flags & kCContiguous) != 0) == c_contig && ((a->flags & kWriteable) != 0) == writable &&
              !v.readonly == writable;
    for (int k = 0; ok && k < v.ndim; ++k)
        ok = a->dimensions[k] == v.shape[k] && a->strides[k] == v.strides[k];
    PyBuffer_Release(&v);
    return ok;
}

// numpy.ndarray when the mirrored layout checks out on this NumPy, else nullptr.
inline PyTypeObject* checked_ndarray_type() {
    if (!little_endian()) return nullptr;
    PyObject* np = PyImport_ImportModule("numpy");
    if (!np) {
        PyErr_Clear();
        return nullptr;
    }
    PyTypeObject* type = nullptr;
    PyObject* nd = PyObject_GetAttrString(np, "ndarray");
    PyObject* f = PyRun_String(
        "(lambda np: (lambda a: (a, a.T, np.arange(4.0)[::2], np.zeros(3, np.int8), "
        "np.frombuffer(bytes(16))))(np.arange(6.0).reshape(2, 3)))",
        Py_eval_input, PyModule_GetDict(np), PyModule_GetDict(np));
    PyObject* made = f ? PyObject_CallOneArg(f, np) : nullptr;
    if (nd && PyType_Check(nd) && made && PyTuple_Check(made) && PyTuple_GET_SIZE(made) == 5) {
        bool ok = true;
        for (Py_ssize_t i = 0; i < 5; ++i) ok = ok && Py_TYPE(PyTuple_GET_ITEM(made, i)) == reinterpret_cast<PyTypeObject*>(nd);
        ok = ok && agrees(PyTuple_GET_ITEM(made, 0), 'd', 12, true, true) &&
             agrees(PyTuple_GET_ITEM(made, 1), 'd', 12, false, true) &&
             agrees(PyTuple_GET_ITEM(made, 2), 'd', 12, false, true) &&
             agrees(PyTuple_GET_ITEM(made, 3), 'b', 1, true, true) &&
             agrees(PyTuple_GET_ITEM(made, 4), 'd', 12, true, false);
        if (ok) {
            type = reinterpret_cast<PyTypeObject*>(nd);
            Py_INCREF(nd);  // held for the life of the process
        }
    }
    if (PyErr_Occurred()) PyErr_Clear();
    Py_XDECREF(made);
    Py_XDECREF(f);
    Py_XDECREF(nd);
    Py_DECREF(np);
    return type;
}

inline PyTypeObject* ndarray_type() {
    static PyTypeObject* const type = checked_ndarray_type();
    return type;
}
}  // namespace npy_detail

// A NumPy array's data, shape and strides read directly (see above).
struct FastArray {
    char* data = nullptr;
    int ndim = 0;
    const Py_ssize_t* shape = nullptr;
    const Py_ssize_t* strides = nullptr;
    bool c_contiguous = false;
};

// `o`'s fields when it is an exact numpy.ndarray of item type `type` ('d' float64, 'b'
// int8), aligned, in native byte order (writable too when asked), and the fast path is on;
// false otherwise (the caller then takes the buffer protocol, which decides as before).
inline bool fast_array(PyObject* o, char type, bool writable, FastArray& out) {
    using namespace npy_detail;
    PyTypeObject* nd = ndarray_type();
    if (nd == nullptr || Py_TYPE(o) != nd) return false;
    const auto* a = reinterpret_cast<const ArrayFields*>(o);
    const auto* d = reinterpret_cast<const DescrFields*>(a->descr);
    if (d->type != type || d->type_num != (type == 'd' ? 12 : 1) || d->byteorder == '>') return false;
    const unsigned flags = static_cast<unsigned>(a->flags);
    if (!(flags & kAligned)) return false;
    if (writable && (!(flags & kWriteable) || (flags & kWarnOnWrite))) return false;
    out.data = a->data;
    out.ndim = a->nd;
    out.shape = a->dimensions;
    out.strides = a->strides;
    out.c_contiguous = (flags & kCContiguous) != 0;
    return true;
}

}  // namespace qpik::bind

// Bindings of the core layer (qpik._engine.core), named for Python in qpik/core/kernels.py
// (tuples or preallocated NumPy arrays: float64, int64 status arrays, int8 active sets;
// Python scalars).
// Every shape is checked here, so a bad argument raises ValueError instead of reading
// out of bounds.
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bind.hpp"
#include "core/cascade.hpp"
#include "core/linalg.hpp"
#include "core/qp.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using namespace qpik;
using namespace qpik::bind;
namespace core = qpik::core;

using InI8_1 = In<i8, 1>;
using InI8_2 = In<i8, 2>;
using InI64_1 = In<i64, 1>;
using Arr = nb::ndarray<nb::numpy, double>;

inline i64 rows(const In2& a) { return static_cast<i64>(a.shape(0)); }
inline i64 cols(const In2& a) { return static_cast<i64>(a.shape(1)); }
template <class A>
inline i64 len(const A& a) { return static_cast<i64>(a.shape(0)); }

inline void need(bool ok, const std::string& what) {
    if (!ok) throw BadArgument(what);
}

// The QP's arguments: H (n, n), c (n,), C (m, n), lo, hi, warm (m,).
void check_qp(const char* fn, const In2& H, const In1& c, const In2& C, const In1& lo, const In1& hi,
              const InI8_1& warm) {
    std::string f(fn);
    i64 n = rows(H);
    need(cols(H) == n, f + ": H must be square (n, n)");
    need(len(c) == n, f + ": c must have shape (n,)");
    need(cols(C) == n, f + ": C must have shape (m, n)");
    i64 m = rows(C);
    need(len(lo) == m && len(hi) == m, f + ": lo and hi must have shape (m,)");
    need(len(warm) == m, f + ": warm must have shape (m,)");
}

nb::tuple qp_tuple(core::QPResult&& r) {
    return nb::make_tuple(to_numpy(std::move(r.x)), r.status, r.iterations, to_numpy(std::move(r.active)));
}

// A read-only (or writable) view of a Python object's buffer: C-contiguous, of the given
// ndim and item type ('d' float64, 'b' int8); anything else is refused (no conversion).
// An exact NumPy array is read directly (bind.hpp's fast_array: the same data, no
// PyObject_GetBuffer), anything else through the buffer protocol.
struct PyBuf {
    Py_buffer v;              // valid only while held (no zeroing: PyBufs are made on every call)
    bool held = false;        // v holds a buffer (released by release())
    PyObject* fast = nullptr;  // the array read directly (a reference held)
    void* buf = nullptr;
    const Py_ssize_t* shp = nullptr;
    PyBuf() = default;
    PyBuf(const PyBuf&) = delete;
    PyBuf& operator=(const PyBuf&) = delete;
    PyBuf(PyBuf&&) = delete;
    ~PyBuf() { release(); }
    void release() {
        if (held) PyBuffer_Release(&v);
        held = false;
        Py_CLEAR(fast);
    }
    bool get(PyObject* o, char type, int ndim, bool writable = false) {
        release();
        FastArray fa;
        if (fast_array(o, type, writable, fa)) {
            if (fa.ndim != ndim || !fa.c_contiguous) return false;
            Py_INCREF(o);
            fast = o;
            buf = fa.data;
            shp = fa.shape;
            return true;
        }
        int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(o, &v, flags) != 0) {
            PyErr_Clear();
            return false;
        }
        held = true;
        buf = v.buf;
        shp = v.shape;
        if (v.ndim != ndim || v.itemsize != (type == 'd' ? 8 : 1) || v.format == nullptr) return false;
        const char* f = v.format;
        if (*f == '<' || *f == '=' || *f == '@') ++f;
        return f[0] == type && f[1] == '\0';
    }
    i64 shape(int i) const { return static_cast<i64>(shp[i]); }
    template <class T>
    T* data() const { return static_cast<T*>(buf); }
};


// numpy.empty(shape) (float64) or numpy.empty(shape, numpy.int8): a new array, nullptr (the
// Python error cleared) on failure.
struct NumpyEmpty {
    PyObject* empty = nullptr;  // numpy.empty and numpy.int8, held for the life of the process
    PyObject* int8 = nullptr;
};
inline const NumpyEmpty& numpy_empty_fns() {
    static const NumpyEmpty f = [] {
        NumpyEmpty r;
        PyObject* np = PyImport_ImportModule("numpy");
        if (np) {
            r.empty = PyObject_GetAttrString(np, "empty");
            r.int8 = PyObject_GetAttrString(np, "int8");
            Py_DECREF(np);
        }
        if (PyErr_Occurred()) PyErr_Clear();
        return r;
    }();
    return f;
}
inline PyObject* numpy_empty(PyObject* shape, bool int8) {
    const NumpyEmpty& f = numpy_empty_fns();
    if (!f.empty || !f.int8 || !shape) {
        Py_XDECREF(shape);
        if (PyErr_Occurred()) PyErr_Clear();
        return nullptr;
    }
    PyObject* args[2] = {shape, f.int8};
    PyObject* out = PyObject_Vectorcall(f.empty, args, int8 ? 2 : 1, nullptr);
    Py_DECREF(shape);
    if (!out) PyErr_Clear();
    return out;
}

// The same new arrays made through NumPy's C API table (the `_ARRAY_API` capsule NumPy's own
// import_array reads; slots 0, 2, 45, 94 are part of NumPy's stable ABI: the ABI version,
// ndarray, PyArray_DescrFromType, PyArray_NewFromDescr), without numpy.empty's Python call
// and argument parsing (about 1.2k instructions an array). Turned on only when, on this
// NumPy, ndarray is the type bind.hpp's fast path reads and arrays made this way match
// numpy.empty's (type, dtype, shape, strides, flags) on arrays made for the check; else every
// array comes from numpy.empty, as before.
namespace npy_c {
using DescrFromType = PyObject* (*)(int);
using NewFromDescr = PyObject* (*)(PyTypeObject*, PyObject*, int, const Py_ssize_t*, const Py_ssize_t*, void*, int,
                                   PyObject*);
struct Api {
    PyTypeObject* type = nullptr;  // nullptr: off
    DescrFromType descr = nullptr;
    NewFromDescr make = nullptr;
};
inline PyObject* make(const Api& a, int type_num, int nd, const Py_ssize_t* dims) {
    PyObject* d = a.descr(type_num);
    return d ? a.make(a.type, d, nd, dims, nullptr, nullptr, 0, nullptr) : nullptr;  // d stolen
}
// Same type, dtype, shape, strides and flags (the data pointers aside).
inline bool same_kind(PyObject* p, PyObject* q) {
    using namespace npy_detail;
    if (!p || !q || Py_TYPE(p) != Py_TYPE(q)) return false;
    const auto* a = reinterpret_cast<const ArrayFields*>(p);
    const auto* b = reinterpret_cast<const ArrayFields*>(q);
    if (a->nd != b->nd || a->flags != b->flags || a->descr != b->descr || a->base != nullptr || b->base != nullptr)
        return false;
    for (int k = 0; k < a->nd; ++k)
        if (a->dimensions[k] != b->dimensions[k] || a->strides[k] != b->strides[k]) return false;
    return true;
}
inline Api checked_api() {
    Api api, none;
    PyTypeObject* nd = npy_detail::ndarray_type();
    if (!nd) return none;
    PyObject* mod = PyImport_ImportModule("numpy._core._multiarray_umath");
    if (!mod) {
        PyErr_Clear();
        mod = PyImport_ImportModule("numpy.core._multiarray_umath");
    }
    PyObject* cap = mod ? PyObject_GetAttrString(mod, "_ARRAY_API") : nullptr;
    void** table = cap && PyCapsule_CheckExact(cap) ? static_cast<void**>(PyCapsule_GetPointer(cap, nullptr)) : nullptr;
    // The capsule's table lives as long as NumPy's module (held for the life of the process).
    if (table && reinterpret_cast<PyTypeObject*>(table[2]) == nd) {
        api.type = nd;
        api.descr = reinterpret_cast<DescrFromType>(table[45]);
        api.make = reinterpret_cast<NewFromDescr>(table[94]);
        bool ok = true;
        const Py_ssize_t d1[1] = {5}, d2[2] = {3, 4}, d0[1] = {0}, dz[2] = {0, 2};
        struct Case {
            int type_num, nd;
            const Py_ssize_t* dims;
            PyObject* shape;
            bool int8;
        } cases[] = {{12, 1, d1, Py_BuildValue("(n)", d1[0]), false},
                     {1, 2, d2, Py_BuildValue("(nn)", d2[0], d2[1]), true},
                     {12, 1, d0, Py_BuildValue("(n)", d0[0]), false},
                     {1, 2, dz, Py_BuildValue("(nn)", dz[0], dz[1]), true}};
        for (const Case& c : cases) {
            PyObject* mine = make(api, c.type_num, c.nd, c.dims);
            PyObject* theirs = numpy_empty(c.shape, c.int8);  // shape stolen
            FastArray fa;
            ok = ok && same_kind(mine, theirs) && fast_array(mine, c.int8 ? 'b' : 'd', true, fa) && fa.c_contiguous;
            Py_XDECREF(mine);
            Py_XDECREF(theirs);
        }
        if (!ok) api = none;
    }
    if (PyErr_Occurred()) PyErr_Clear();
    Py_XDECREF(cap);
    Py_XDECREF(mod);
    return api;
}
inline const Api& api() {
    static const Api a = checked_api();
    return a;
}
}  // namespace npy_c

// A new float64 (n,) array, or a new int8 (L, w) one: numpy.empty's, made through the C API
// when it checked out (above). nullptr (the Python error cleared) on failure.
inline PyObject* new_x(i64 n) {
    const npy_c::Api& a = npy_c::api();
    if (!a.type) return numpy_empty(PyLong_FromLongLong(n), false);
    const Py_ssize_t dims[1] = {static_cast<Py_ssize_t>(n)};
    PyObject* out = npy_c::make(a, 12, 1, dims);
    if (!out) PyErr_Clear();
    return out;
}
inline PyObject* new_active(i64 L, i64 w) {
    const npy_c::Api& a = npy_c::api();
    if (!a.type) {
        PyObject* shape = PyTuple_New(2);
        if (shape) {
            PyTuple_SET_ITEM(shape, 0, PyLong_FromLongLong(L));
            PyTuple_SET_ITEM(shape, 1, PyLong_FromLongLong(w));
            if (!PyTuple_GET_ITEM(shape, 0) || !PyTuple_GET_ITEM(shape, 1)) Py_CLEAR(shape);
        }
        return numpy_empty(shape, true);
    }
    const Py_ssize_t dims[2] = {static_cast<Py_ssize_t>(L), static_cast<Py_ssize_t>(w)};
    PyObject* out = npy_c::make(a, 1, 2, dims);
    if (!out) PyErr_Clear();
    return out;
}

// Interned attribute names of the objects solve_levels reads and builds (made once).
struct Names {
    PyObject *A, *b, *regularization, *weights;
    PyObject *x, *status, *active, *primal, *raw;
};
inline const Names& names() {
    static const Names n = [] {
        auto s = [](const char* v) { return PyUnicode_InternFromString(v); };
        return Names{s("A"), s("b"), s("regularization"), s("weights"), s("x"), s("status"), s("active"),
                     s("primal"), s("_raw")};
    }();
    return n;
}

inline PyObject* empty_tuple() {
    static PyObject* t = PyTuple_New(0);
    return t;
}

// An instance of `type` made as object.__new__(type) with its fields set through the generic
// setattr (as object.__setattr__: a frozen dataclass's fields too); values are stolen.
// nullptr (with the Python error set) on failure.
inline PyObject* new_with_fields(PyTypeObject* type, std::initializer_list<std::pair<PyObject*, PyObject*>> fields) {
    bool ok = true;
    for (const auto& f : fields) ok = ok && f.second != nullptr;
    PyObject* obj = ok ? PyBaseObject_Type.tp_new(type, empty_tuple(), nullptr) : nullptr;
    for (const auto& f : fields) {
        if (obj && PyObject_GenericSetAttr(obj, f.first, f.second) != 0) {
            Py_DECREF(obj);
            obj = nullptr;
        }
        Py_XDECREF(f.second);
    }
    return obj;
}

// new_with_fields with the fields set by `fill` (a Python function fill(obj, *values) that
// sets them in that order and returns obj, or None for new_with_fields): the interpreter's
// specialised attribute stores cost less than the generic setattr (about 1k instructions
// fewer for ten fields). Values are stolen; nullptr (with the Python error set) on failure.
inline PyObject* new_filled(PyTypeObject* type, PyObject* fill,
                            std::initializer_list<std::pair<PyObject*, PyObject*>> fields) {
    if (fill == Py_None || fields.size() > 15) return new_with_fields(type, fields);
    PyObject* args[16];
    size_t k = 1;
    bool ok = true;
    for (const auto& f : fields) {
        ok = ok && f.second != nullptr;
        args[k++] = f.second;
    }
    PyObject* obj = ok ? PyBaseObject_Type.tp_new(type, empty_tuple(), nullptr) : nullptr;
    PyObject* out = nullptr;
    if (obj) {
        args[0] = obj;
        out = PyObject_Vectorcall(fill, args, k, nullptr);
        Py_DECREF(obj);
    }
    for (const auto& f : fields) Py_XDECREF(f.second);
    return out;
}

// src[j], j < n, copied into dst (when given) two lanes at a time, with `z` += v * 0 per lane
// (NaN exactly once some v is NaN or infinite; z[2] takes an odd n's last entry): the
// finiteness of many rows decided by one test of z at the end (finite_sum), none per entry.
// Returns whether some entry has |v| > 0 (for finite entries, the same as their sum of |v|
// being > 0).
struct FiniteSum {
    core::simd::v2d z = {0.0, 0.0};
    double zt = 0.0;
    bool ok() const { return z[0] == z[0] && z[1] == z[1] && zt == zt; }
};
__attribute__((always_inline)) inline bool copy_scan(const double* src, double* dst, i64 n, FiniteSum& f) {
    namespace sd = core::simd;
    sd::v2i bits = {0, 0};
    const sd::v2i mag = {0x7fffffffffffffffLL, 0x7fffffffffffffffLL};
    i64 j = 0;
    for (; j + 2 <= n; j += 2) {
        sd::v2d v = sd::load(src + j);
        if (dst) sd::store(dst + j, v);
        f.z += v * sd::splat(0.0);
        sd::v2i b;
        std::memcpy(&b, &v, sizeof v);
        bits |= b & mag;
    }
    long long bt = 0;
    if (j < n) {
        double v = src[j];
        if (dst) dst[j] = v;
        f.zt += v * 0.0;
        std::memcpy(&bt, &v, sizeof v);
        bt &= 0x7fffffffffffffffLL;
    }
    return (bits[0] | bits[1] | bt) != 0;
}
inline bool all_finite(const double* src, i64 n) {
    FiniteSum f;
    copy_scan(src, nullptr, n, f);
    return f.ok();
}

// The result object of solve_levels (see there); raises the Python error on failure. It
// carries x, status, active and primal as fields, and the per-level figures as the float64
// bytes ``_raw`` (L levels): residuals, damping (lambda^2), iterations (whole numbers, exact
// in a double), the (L, 4) certificate measures, sigma, then, where a level's sigma was
// deferred (CascadeResult::deferred), the deferred store. The result class builds the lists
// residuals, damping, iterations, backend, sigma and certificate from them on first access
// (HierarchyResult.__getattr__; the same values): a caller that reads x and status only
// never pays for them.
inline nb::object result_object(PyTypeObject* result_type, PyObject* fill, PyObject* statuses, PyObject* x,
                                PyObject* active, const core::CascadeResult& r, i64 L) {
    const Names& nm = names();
    PyObject* status = PyList_New(L);
    for (i64 k = 0; k < L && status; ++k) {
        i64 code = r.status[k] >= 0 && r.status[k] < 6 ? r.status[k] : core::NUMERICAL;
        PyObject* st = PyTuple_GET_ITEM(statuses, code);
        Py_INCREF(st);
        PyList_SET_ITEM(status, k, st);
    }
    if (!status) throw nb::python_error();
    bool deferred = false;
    for (i64 k = 0; k < L && k < static_cast<i64>(r.deferred.size()); ++k) deferred = deferred || r.deferred[k] != -1.0;
    const size_t l = static_cast<size_t>(L), store = deferred ? r.deferred.size() : 0;
    PyObject* raw = PyBytes_FromStringAndSize(nullptr, static_cast<Py_ssize_t>((8 * l + store) * sizeof(double)));
    if (raw) {
        double* dst = reinterpret_cast<double*>(PyBytes_AS_STRING(raw));
        for (size_t k = 0; k < l; ++k) {
            dst[k] = r.residuals[k];
            dst[l + k] = r.lam2[k];
            dst[2 * l + k] = static_cast<double>(r.iterations[k]);
            dst[7 * l + k] = r.sigma[k];
        }
        std::memcpy(dst + 3 * l, r.certificate.data(), 4 * l * sizeof(double));
        if (store) std::memcpy(dst + 8 * l, r.deferred.data(), store * sizeof(double));
    }
    Py_INCREF(x);
    Py_INCREF(active);
    PyObject* obj = new_filled(result_type, fill,
                               {{nm.x, x}, {nm.status, status}, {nm.active, active}, {nm.raw, raw},
                                {nm.primal, PyFloat_FromDouble(r.primal)}});
    if (!obj) throw nb::python_error();
    return nb::steal(obj);
}

}  // namespace

void bind_core(nb::module_& m) {
    m.attr("SOLVED") = static_cast<i64>(core::SOLVED);
    m.attr("MAX_ITER") = static_cast<i64>(core::MAX_ITER);
    m.attr("INFEASIBLE") = static_cast<i64>(core::INFEASIBLE);
    m.attr("KEPT_PREVIOUS") = static_cast<i64>(core::KEPT_PREVIOUS);
    m.attr("NUMERICAL") = static_cast<i64>(core::NUMERICAL);
    m.attr("NOT_REACHED") = static_cast<i64>(core::NOT_REACHED);

    nb::class_<core::Workspace>(
        m, "CascadeWorkspace",
        "The storage of one solver's cascade (solve_levels / solve_cascade), kept between its "
        "solves so that a solve of the same sizes allocates no matrices: one per solver, never "
        "shared between threads. Holds no state but capacity (the answers do not depend on it); "
        "a copy or an unpickled one starts empty.")
        .def(nb::init<>())
        .def("__getstate__", [](const core::Workspace&) { return nb::make_tuple(); })
        .def("__setstate__", [](core::Workspace& ws, const nb::tuple&) { new (&ws) core::Workspace(); });

    m.def(
        "cholesky_into",
        [](In2 G, i64 n, double shift, Out2 L) {
            need(n >= 0, "cholesky_into: n must be >= 0");
            need(rows(G) >= n && cols(G) >= n, "cholesky_into: G must be at least (n, n)");
            need(static_cast<i64>(L.shape(0)) >= n && static_cast<i64>(L.shape(1)) >= n,
                 "cholesky_into: L must be at least (n, n)");
            return core::cholesky_into(cmat(G), n, shift, mat(L));
        },
        "G"_a, "n"_a, "shift"_a, "L"_a.noconvert(),
        "Cholesky factor of G[:n, :n] - shift I written into the lower triangle of L[:n, :n]; "
        "False as soon as a pivot is not positive.");

    m.def(
        "solve_qp",
        [](In2 H, In1 c, In2 C, In1 lo, In1 hi, InI8_1 warm, i64 max_iter, double tol, bool canonical) {
            check_qp("solve_qp", H, c, C, lo, hi, warm);
            return qp_tuple(core::solve_qp(cmat(H), cvec(c), cmat(C), cvec(lo), cvec(hi),
                                           VecRefT<const i8>(warm.data(), len(warm)), max_iter, tol, canonical));
        },
        "H"_a, "c"_a, "C"_a, "lo"_a, "hi"_a, "warm"_a, "max_iter"_a, "tol"_a, "canonical"_a,
        "min 1/2 x^T H x + c^T x s.t. lo <= C x <= hi: (x, status, iterations, active).");

    m.def(
        "solve_level",
        [](In2 H, In1 c, In2 C, In1 lo, In1 hi, InI8_1 warm, i64 max_iter, double tol, bool lower,
           bool canonical) {
            check_qp("solve_level", H, c, C, lo, hi, warm);
            return qp_tuple(core::solve_level(cmat(H), cvec(c), cmat(C), cvec(lo), cvec(hi),
                                              VecRefT<const i8>(warm.data(), len(warm)), max_iter, tol, lower,
                                              canonical));
        },
        "H"_a, "c"_a, "C"_a, "lo"_a, "hi"_a, "warm"_a, "max_iter"_a, "tol"_a, "lower"_a, "canonical"_a,
        "solve_qp for one level, retried with widened rows on a numerical failure.");

    m.def(
        "active_guess",
        [](In1 x, In2 C, In1 lo, In1 hi) {
            need(cols(C) == len(x), "active_guess: C must have shape (m, n) with x (n,)");
            need(len(lo) == rows(C) && len(hi) == rows(C), "active_guess: lo and hi must have shape (m,)");
            return to_numpy(core::active_guess(cvec(x), cmat(C), cvec(lo), cvec(hi)));
        },
        "x"_a, "C"_a, "lo"_a, "hi"_a, "Rows at a bound at x: +1 lower, -1 upper (int8).");

    m.def(
        "project_level",
        [](In2 A, In1 w, In2 Z, double rank_tol) {
            need(len(w) == rows(A), "project_level: w must have shape (m,)");
            need(rows(Z) == cols(A), "project_level: Z must have shape (n, r)");
            core::Projection p = core::project_level(cmat(A), cvec(w), cmat(Z), rank_tol);
            return nb::make_tuple(to_numpy(std::move(p.AZ)), p.sigma, p.rank, to_numpy(std::move(p.Zn)));
        },
        "A"_a, "w"_a, "Z"_a, "rank_tol"_a, "(A Z, sigma, rank, Zn) of a level projected into Z.");

    m.def(
        "level_damping",
        [](In2 A, In1 b, In1 w, In1 d, double sigma, double threshold, double max_damping, double error_scale) {
            need(len(b) == rows(A) && len(w) == rows(A), "level_damping: b and w must have shape (m,)");
            need(len(d) == cols(A), "level_damping: d must have shape (n,)");
            return core::level_damping(cmat(A), cvec(b), cvec(w), d.data(), sigma, threshold, max_damping,
                                       error_scale);
        },
        "A"_a, "b"_a, "w"_a, "d"_a, "sigma"_a, "threshold"_a, "max_damping"_a, "error_scale"_a,
        "The lambda^2 a level gets.");

    m.def(
        "hypot_inline",
        [](In1 x, In1 y, Out1 out) {
            need(len(y) == len(x) && len(out) == len(x), "hypot_inline: x, y, out must have the same length");
            for (i64 i = 0; i < len(x); ++i) out.data()[i] = core::detail::hypot_inline(x.data()[i], y.data()[i]);
        },
        "x"_a, "y"_a, "out"_a.noconvert(),
        "out[i] = hypot(x[i], y[i]) as the dual method's rotations take it (qp.hpp's hypot_inline).");

    m.def(
        "resolve_sigma",
        [](In1 sigma, In1 store) {
            const i64 L = len(sigma), n = len(store);
            need(n >= L, "resolve_sigma: store must hold at least L entries");
            nb::list out;
            for (i64 k = 0; k < L; ++k) {
                const double s = sigma(k);
                out.append(s == s ? s : core::deferred_sigma(store.data(), n, L, k, s));
            }
            return out;
        },
        "sigma"_a, "store"_a,
        "The per-level sigma (L,) with each NaN of a level the cascade deferred (its defer_sigma store: L header "
        "entries, then the records) replaced by the sigma its ranking gives (the same bits as without deferral).");

    m.def("damping_of", &core::damping_of, "sigma"_a, "threshold"_a, "max_damping"_a,
          "lambda^2 driven by sigma: max_damping^2 (1 - (sigma / threshold)^2) below the threshold.");

    m.def(
        "reduced_qp",
        [](In2 A, In1 b, In2 AZ, In2 Z, In1 d, double reg, In1 lb, In1 ub, In2 G, In1 h) {
            i64 mm_ = rows(A), n = cols(A), r = cols(Z), p = rows(G);
            need(len(b) == mm_, "reduced_qp: b must have shape (m,)");
            need(rows(Z) == n, "reduced_qp: Z must have shape (n, r)");
            need(rows(AZ) == mm_ && cols(AZ) == r, "reduced_qp: AZ must have shape (m, r)");
            need(len(d) == n && len(lb) == n && len(ub) == n, "reduced_qp: d, lb, ub must have shape (n,)");
            need(p == 0 || cols(G) == n, "reduced_qp: G must have shape (p, n)");
            need(len(h) == p, "reduced_qp: h must have shape (p,)");
            core::ReducedQP q = core::reduced_qp(cmat(A), cvec(b), cmat(AZ), cmat(Z), d.data(), reg, cvec(lb),
                                                 cvec(ub), cmat(G), cvec(h));
            return nb::make_tuple(to_numpy(std::move(q.H)), to_numpy(std::move(q.c)), to_numpy(std::move(q.C)),
                                  to_numpy(std::move(q.lo)), to_numpy(std::move(q.hi)));
        },
        "A"_a, "b"_a, "AZ"_a, "Z"_a, "d"_a, "reg"_a, "lb"_a, "ub"_a, "G"_a, "h"_a,
        "(H, c, C, lo, hi): the level's QP in null-space coordinates dq = d + Z z.");

    m.def(
        "drop_pinned",
        [](In2 Z, In1 d, In1 lb, In1 ub, In2 G, In1 h) {
            i64 n = rows(Z), p = rows(G);
            need(len(d) == n && len(lb) == n && len(ub) == n, "drop_pinned: d, lb, ub must have shape (n,)");
            need(p == 0 || cols(G) == n, "drop_pinned: G must have shape (p, n)");
            need(len(h) == p, "drop_pinned: h must have shape (p,)");
            Mat Zm(n, cols(Z));
            for (i64 i = 0; i < n; ++i)
                for (i64 j = 0; j < cols(Z); ++j) Zm(i, j) = cmat(Z)(i, j);
            Vec dv(d.data(), d.data() + n);
            core::drop_pinned(Zm, dv, cvec(lb), cvec(ub), cmat(G), cvec(h));
            return to_numpy(std::move(Zm));
        },
        "Z"_a, "d"_a, "lb"_a, "ub"_a, "G"_a, "h"_a,
        "Z without the directions of the rows pinned on their bounds at d (the levels' "
        "implied equalities; Z itself when none).");

    m.def(
        "tighten",
        [](Out1 lb, Out1 ub, InI64_1 dofs, In1 lower, In1 upper) {
            i64 n = len(lb), k = len(dofs);
            need(len(ub) == n, "tighten: lb and ub must have the same shape");
            need(len(lower) == k && len(upper) == k, "tighten: lower and upper must have the shape of dofs");
            for (i64 j = 0; j < k; ++j) need(dofs.data()[j] >= 0 && dofs.data()[j] < n, "tighten: dof out of range");
            core::tighten(vec(lb), vec(ub), VecRefT<const i64>(dofs.data(), k), cvec(lower), cvec(upper));
        },
        "lb"_a.noconvert(), "ub"_a.noconvert(), "dofs"_a, "lower"_a, "upper"_a,
        "lb[dofs] = max(lb[dofs], lower), ub[dofs] = min(ub[dofs], upper) in place.");

    m.def(
        "merge_boxes",
        [](In1 hard_lb, In1 hard_ub, In1 pos_lb, In1 pos_ub) {
            i64 n = len(hard_lb);
            need(len(hard_ub) == n && len(pos_lb) == n && len(pos_ub) == n,
                 "merge_boxes: the four bounds must have the same shape (n,)");
            Vec lb, ub;
            i64 i = core::merge_boxes(cvec(hard_lb), cvec(hard_ub), cvec(pos_lb), cvec(pos_ub), lb, ub);
            return nb::make_tuple(to_numpy(std::move(lb)), to_numpy(std::move(ub)), i);
        },
        "hard_lb"_a, "hard_ub"_a, "pos_lb"_a, "pos_ub"_a,
        "(lb, ub, i): the merged box and the first dof whose hard bounds conflict (-1: none).");

    m.def(
        "certified_level",
        [](In2 A, In1 b, In2 AZ, In2 Z, In1 d, double rho, In1 lb, In1 ub, In2 G, In1 h, InI8_1 active,
           i64 status, i64 max_iter, bool lower) {
            i64 mm_ = rows(A), n = cols(A), r = cols(Z), p = rows(G);
            need(len(b) == mm_, "certified_level: b must have shape (m,)");
            need(rows(Z) == n, "certified_level: Z must have shape (n, r)");
            need(rows(AZ) == mm_ && cols(AZ) == r, "certified_level: AZ must have shape (m, r)");
            need(len(d) == n && len(lb) == n && len(ub) == n, "certified_level: d, lb, ub must have shape (n,)");
            need(p == 0 || cols(G) == n, "certified_level: G must have shape (p, n)");
            need(len(h) == p, "certified_level: h must have shape (p,)");
            need(len(active) == n + p, "certified_level: active must have shape (n + p,)");
            Vec dv(d.data(), d.data() + n);
            core::CertifiedLevel c = core::certified_level(
                cmat(A), cvec(b), cmat(AZ), cmat(Z), dv, rho, cvec(lb), cvec(ub), cmat(G), cvec(h),
                VecRefT<const i8>(active.data(), n + p), status, max_iter, lower);
            Vec cert{c.cert.primal, c.cert.stationarity, c.cert.dual, c.cert.complementarity};
            return nb::make_tuple(c.ok, to_numpy(std::move(c.z)), to_numpy(std::move(cert)),
                                  to_numpy(std::move(c.active)));
        },
        "A"_a, "b"_a, "AZ"_a, "Z"_a, "d"_a, "rho"_a, "lb"_a, "ub"_a, "G"_a, "h"_a, "active"_a, "status"_a,
        "max_iter"_a, "lower"_a,
        "A level made exact from a QP answer's active set and certified: (ok, z, certificate (4,), active).");

    m.def(
        "certify_point",
        [](In2 A, In1 b, double rho, In2 Z, In1 x, In1 lb, In1 ub, In2 G, In1 h) {
            i64 mm_ = rows(A), n = cols(A), p = rows(G);
            need(len(b) == mm_, "certify_point: b must have shape (m,)");
            need(rows(Z) == n, "certify_point: Z must have shape (n, r)");
            need(len(x) == n && len(lb) == n && len(ub) == n, "certify_point: x, lb, ub must have shape (n,)");
            need(p == 0 || cols(G) == n, "certify_point: G must have shape (p, n)");
            need(len(h) == p, "certify_point: h must have shape (p,)");
            Vec xv(x.data(), x.data() + n);
            bool stat = mm_ > 0 && cols(Z) > 0;
            core::Certificate c = core::certify_level(cmat(A), cvec(b), rho, cmat(Z), xv, cvec(lb), cvec(ub), cmat(G),
                                                      cvec(h), {}, {}, {}, 0, stat);
            Vec cert{c.primal, stat ? c.stationarity : 0.0, 0.0, 0.0};
            return to_numpy(std::move(cert));
        },
        "A"_a, "b"_a, "rho"_a, "Z"_a, "x"_a, "lb"_a, "ub"_a, "G"_a, "h"_a,
        "The certificate (4,) of a level at the point x with no working set (a level not "
        "reached: which conditions fail there); stationarity 0 for a level with no rows or "
        "no freedom.");

    auto solve_levels = [](nb::handle levels_h, nb::handle lb_h, nb::handle ub_h, nb::handle G_h, nb::handle h_h, double threshold,
           double max_damping, double error_scale, double rank_tol, i64 max_iter, double tol, nb::handle warm_h,
           nb::handle x_h, nb::handle active_h, nb::handle kinds_h, core::Workspace* ws,
           double lower_trust) -> nb::object {
            // The whole solve from the levels themselves (objects with A, b, regularization,
            // weights): checks (as HierarchyProblem.validate), stacking and the cascade in one
            // call, the answer written into x and active (preallocated by the caller) and
            // returned as a result object built here (kinds: the result class, the
            // certificate class, the statuses by code, the backend label, and optionally the
            // function that sets the fields: new_filled), whose fields are set directly (as
            // the dataclass __init__ would, by kinds[4] when given, else the generic setattr). The arrays are read through the
            // buffer protocol (no conversion). None when an argument does not pass or needs a
            // conversion (the caller then validates in Python, which names the field), or
            // when a level did not settle (MAX_ITER, NUMERICAL: the caller's fallback).
            nb::object none = nb::none();
            if (!(lower_trust >= 0.0 && lower_trust <= 1.0)) return none;  // (NaN too: the checks name it)
            PyBuf lb, ub, G, h, xo, act;
            if (!lb.get(lb_h.ptr(), 'd', 1) || !ub.get(ub_h.ptr(), 'd', 1) || !G.get(G_h.ptr(), 'd', 2) ||
                !h.get(h_h.ptr(), 'd', 1))
                return none;
            i64 n = lb.shape(0), p = G.shape(0);
            if (ub.shape(0) != n || G.shape(1) != n || h.shape(0) != p) return none;
            const double* lbp = lb.data<double>();
            const double* ubp = ub.data<double>();
            const double* Gp = G.data<double>();
            const double* hp = h.data<double>();
            // (NaN, lb > ub, lb = +inf, ub = -inf or h = -inf: bounds nothing meets, which
            // HierarchyProblem.validate names)
            constexpr double inf = std::numeric_limits<double>::infinity();
            for (i64 i = 0; i < n; ++i)
                if (!(lbp[i] <= ubp[i]) || lbp[i] == inf || ubp[i] == -inf) return none;
            if (!all_finite(Gp, p * n)) return none;
            for (i64 i = 0; i < p; ++i)
                if (std::isnan(hp[i]) || hp[i] == -inf) return none;
            if (!PyList_Check(levels_h.ptr()) && !PyTuple_Check(levels_h.ptr())) return none;
            i64 L = static_cast<i64>(PySequence_Fast_GET_SIZE(levels_h.ptr()));
            if (L == 0) return none;
            // x and active: the caller's, or new arrays made here (numpy.empty) when None
            nb::object x_new, act_new;
            PyObject* x_p = x_h.ptr();
            PyObject* act_p = active_h.ptr();
            if (x_h.is_none()) {
                x_new = nb::steal(new_x(n));
                if (!x_new.is_valid()) return none;
                x_p = x_new.ptr();
            }
            if (active_h.is_none()) {
                act_new = nb::steal(new_active(L, n + p));
                if (!act_new.is_valid()) return none;
                act_p = act_new.ptr();
            }
            if (!xo.get(x_p, 'd', 1, true) || xo.shape(0) != n) return none;
            if (!act.get(act_p, 'b', 2, true) || act.shape(0) != L || act.shape(1) != n + p) return none;
            if (!PyTuple_Check(kinds_h.ptr()) || PyTuple_GET_SIZE(kinds_h.ptr()) < 4 || PyTuple_GET_SIZE(kinds_h.ptr()) > 5)
                return none;
            PyObject* result_type = PyTuple_GET_ITEM(kinds_h.ptr(), 0);
            PyObject* cert_type = PyTuple_GET_ITEM(kinds_h.ptr(), 1);  // built by kinds[0] (from its _raw)
            PyObject* statuses = PyTuple_GET_ITEM(kinds_h.ptr(), 2);
            // (kinds[3], the backend label, is the result class's to read: its lists are built there)
            // kinds[4], when given: the function that sets the result's fields (new_filled)
            PyObject* fill = PyTuple_GET_SIZE(kinds_h.ptr()) == 5 ? PyTuple_GET_ITEM(kinds_h.ptr(), 4) : Py_None;
            if (fill != Py_None && !PyCallable_Check(fill)) return none;
            if (!PyType_Check(result_type) || !PyType_Check(cert_type) || !PyTuple_Check(statuses) ||
                PyTuple_GET_SIZE(statuses) != 6)
                return none;
            // The caller's storage (ws), else storage of its own: the stacked problem and the
            // result (every entry written by this call; nothing of a previous one is read).
            // (a unique_ptr, not an optional: the optional of the large Workspace cost about 600
            // instructions a call even when left empty)
            std::unique_ptr<core::Workspace> local;
            if (!ws) local = std::make_unique<core::Workspace>();
            core::Workspace& wsr = ws ? *ws : *local;
            // Level by level: its buffers read, checked and its rows stacked (then released);
            // any check that fails returns None, as with the checks taken in any order.
            core::Workspace::Stacked& st = wsr.stacked;
            IVec& starts = st.starts;
            starts.assign(static_cast<size_t>(L) + 1, 0);
            Vec& reg = st.reg;
            core::shape(reg, static_cast<size_t>(L));  // every entry written below
            Mat& A = st.A;
            Vec& b = st.b;
            Vec& w = st.w;
            {
                i64 M = 0;  // rows stacked so far
                PyBuf ab, bb, wb;
                for (i64 k = 0; k < L; ++k) {
                    PyObject* level = PySequence_Fast_GET_ITEM(levels_h.ptr(), k);
                    nb::object a = nb::steal(PyObject_GetAttr(level, names().A));
                    nb::object bo = nb::steal(PyObject_GetAttr(level, names().b));
                    nb::object rr = nb::steal(PyObject_GetAttr(level, names().regularization));
                    nb::object ww = nb::steal(PyObject_GetAttr(level, names().weights));
                    if (!a.is_valid() || !bo.is_valid() || !rr.is_valid() || !ww.is_valid()) {
                        PyErr_Clear();
                        return none;
                    }
                    if (!ab.get(a.ptr(), 'd', 2) || !bb.get(bo.ptr(), 'd', 1)) return none;
                    if (ab.shape(1) != n || bb.shape(0) != ab.shape(0)) return none;
                    if (!PyFloat_Check(rr.ptr()) && !PyLong_Check(rr.ptr())) return none;
                    double r = PyFloat_AsDouble(rr.ptr());
                    if (r == -1.0 && PyErr_Occurred()) {
                        PyErr_Clear();
                        return none;
                    }
                    if (!std::isfinite(r) || !(r >= 0.0)) return none;
                    reg[k] = r;
                    bool has_w = !ww.is_none();
                    if (has_w && (!wb.get(ww.ptr(), 'd', 1) || wb.shape(0) != ab.shape(0))) return none;
                    if (has_w) {  // the rows' costs: finite and >= 0 (else validate names them)
                        const double* wv0 = wb.data<double>();
                        for (i64 i = 0; i < ab.shape(0); ++i)
                            if (!(wv0[i] >= 0.0 && wv0[i] < std::numeric_limits<double>::infinity())) return none;
                    }
                    i64 mk = ab.shape(0);
                    starts[k + 1] = starts[k] + mk;
                    // A's storage grows (kept rows copied) only past its capacity
                    A.rows = M + mk;
                    A.cols = n;
                    if (A.a.size() < static_cast<size_t>((M + mk) * n)) A.a.resize(static_cast<size_t>((M + mk) * n));
                    core::shape(b, static_cast<size_t>(M + mk));
                    core::shape(w, static_cast<size_t>(M + mk));
                    const double* av = ab.data<double>();
                    const double* bv = bb.data<double>();
                    const double* wv = has_w ? wb.data<double>() : nullptr;
                    FiniteSum fin;  // the level's rows and targets tested once, after the copy
                    for (i64 i = 0; i < mk; ++i) {
                        bool nonzero = copy_scan(av + i * n, A.row(M + i), n, fin);
                        b[M + i] = bv[i];
                        w[M + i] = wv ? wv[i] : (nonzero ? 1.0 : 0.0);
                    }
                    copy_scan(bv, nullptr, mk, fin);
                    if (!fin.ok()) return none;
                    M += mk;
                }
            }
            const i8* warm = nullptr;
            PyBuf wbuf;
            if (!warm_h.is_none() && wbuf.get(warm_h.ptr(), 'b', 2) && wbuf.shape(0) == L && wbuf.shape(1) == n + p) {
                warm = wbuf.data<i8>();
            } else {
                st.warm_zero.assign(static_cast<size_t>(L * (n + p)), 0);
                warm = st.warm_zero.data();
            }
            if (max_iter <= 0) max_iter = 10 * (n + p) + 50;
            core::CascadeResult& r = wsr.result;
            core::solve_cascade_into(
                A.cref(), CVecRef(b), CVecRef(w), VecRefT<const i64>(starts.data(), L + 1), CVecRef(reg),
                CVecRef(lbp, n), CVecRef(ubp, n), CMatRef(Gp, p, n), CVecRef(hp, p), threshold, max_damping,
                error_scale, rank_tol, max_iter, tol, MatRefT<const i8>(warm, L, n + p), true, wsr, r, true, true,
                true, lower_trust);
            for (i64 k = 0; k < L; ++k)
                if (r.status[k] == core::MAX_ITER || r.status[k] == core::NUMERICAL) return none;
            std::memcpy(xo.data<double>(), r.dq.data(), static_cast<size_t>(n) * sizeof(double));
            std::memcpy(act.data<i8>(), r.active.data(), static_cast<size_t>(L * (n + p)));
            static_assert(sizeof(double) == 8, "the certificate bytes are float64");
            if (static_cast<i64>(r.certificate.size()) < 4 * L) return none;
            return result_object(reinterpret_cast<PyTypeObject*>(result_type), fill, statuses, x_p, act_p, r, L);
    };
    m.def(
        "solve_levels",
        [solve_levels](nb::handle levels, nb::handle lb, nb::handle ub, nb::handle G, nb::handle h,
                       nb::handle settings) -> nb::object {
            // settings: the tuple (threshold, max_damping, error_scale, rank_tol, max_iter, tol,
            // warm, x, active, kinds, workspace, lower_trust), made once per change of the
            // solver's settings (HierarchySolver._solve_levels_args): one plain call a solve,
            // no argument tuple of 17 to build and convert. A value of another type raises
            // TypeError (the caller's general path then checks and names it).
            PyObject* t = settings.ptr();
            if (!PyTuple_Check(t) || PyTuple_GET_SIZE(t) != 12) throw nb::type_error("solve_levels: settings");
            // (an int past a double's or an i64's range: the same TypeError, the error cleared)
            auto bad = [] {
                PyErr_Clear();
                throw nb::type_error("solve_levels: settings");
            };
            auto real = [t, &bad](Py_ssize_t i) {
                PyObject* o = PyTuple_GET_ITEM(t, i);
                if (!PyFloat_Check(o) && !PyLong_Check(o)) bad();
                double v = PyFloat_AsDouble(o);
                if (v == -1.0 && PyErr_Occurred()) bad();
                return v;
            };
            PyObject* it = PyTuple_GET_ITEM(t, 4);
            if (!PyLong_Check(it)) bad();
            const long long max_iter = PyLong_AsLongLong(it);
            if (max_iter == -1 && PyErr_Occurred()) bad();
            nb::handle wsh = PyTuple_GET_ITEM(t, 10);
            core::Workspace* ws = nullptr;
            if (!wsh.is_none() && !nb::try_cast<core::Workspace*>(wsh, ws)) bad();
            return solve_levels(levels, lb, ub, G, h, real(0), real(1), real(2), real(3), max_iter, real(5),
                                PyTuple_GET_ITEM(t, 6), PyTuple_GET_ITEM(t, 7), PyTuple_GET_ITEM(t, 8),
                                PyTuple_GET_ITEM(t, 9), ws, real(11));
        },
        "levels"_a, "lb"_a, "ub"_a, "G"_a, "h"_a, "settings"_a,
        "solve_levels(levels, lb, ub, G, h, settings): solve_cascade from the levels themselves (a list or tuple of objects with A, b, regularization, weights; float64 "
        "C-contiguous arrays) with HierarchyProblem.validate's checks, dq written into x (n,) and the active sets "
        "into active (L, n + p) int8 (each made here as numpy.empty would when None), returned as kinds[0] (the result "
        "class) with the fields x, status (kinds[2][code] per level), active, _raw and primal: _raw the float64 bytes of "
        "the per-level residuals, damping, iterations, the (L, 4) certificate measures (kinds[1]'s fields), sigma and "
        "the deferred sigma store, from which the result class builds those lists (and backend, kinds[3] per level) on "
        "first access. kinds[4], when given, sets the fields: kinds[4](obj, x, status, active, _raw, primal) on "
        "obj = object.__new__(kinds[0]), returning it. None (x and active untouched) when an "
        "argument does not pass or needs a conversion, or when a level ended in MAX_ITER or NUMERICAL.");

    m.def(
        "solve_cascade",
        [](In2 A, In1 b, In1 w, InI64_1 starts, In1 reg, In1 lb, In1 ub, In2 G, In1 h, double threshold,
           double max_damping, double error_scale, double rank_tol, i64 max_iter, double tol, InI8_2 warm,
           bool canonical, core::Workspace* ws, double lower_trust) {
            i64 M = rows(A), n = len(lb), p = rows(G);
            need(cols(A) == n, "solve_cascade: A must have shape (M, n) with lb (n,)");
            need(len(b) == M && len(w) == M, "solve_cascade: b and w must have shape (M,)");
            need(len(starts) >= 1, "solve_cascade: starts must have shape (L + 1,)");
            i64 L = len(starts) - 1;
            const i64* s = starts.data();
            need(s[0] >= 0 && s[L] <= M, "solve_cascade: starts out of range");
            for (i64 k = 0; k < L; ++k) need(s[k] <= s[k + 1], "solve_cascade: starts must be non-decreasing");
            need(len(reg) == L, "solve_cascade: reg must have shape (L,)");
            need(len(ub) == n, "solve_cascade: ub must have shape (n,)");
            need(p == 0 || cols(G) == n, "solve_cascade: G must have shape (p, n)");
            need(len(h) == p, "solve_cascade: h must have shape (p,)");
            need(static_cast<i64>(warm.shape(0)) == L && static_cast<i64>(warm.shape(1)) == n + p,
                 "solve_cascade: warm must have shape (L, n + p)");
            std::optional<core::Workspace> local;  // only when the caller keeps none (its storage: ws)
            if (!ws) local.emplace();
            need(std::isfinite(lower_trust) && lower_trust >= 0.0 && lower_trust <= 1.0,
                 "solve_cascade: lower_trust must be in [0, 1]");
            core::CascadeResult r;
            core::solve_cascade_into(cmat(A), cvec(b), cvec(w), VecRefT<const i64>(s, L + 1), cvec(reg), cvec(lb),
                                     cvec(ub), cmat(G), cvec(h), threshold, max_damping, error_scale, rank_tol,
                                     max_iter, tol, MatRefT<const i8>(warm.data(), L, n + p), canonical,
                                     ws ? *ws : *local, r, true, true, false, lower_trust);
            size_t Ls = static_cast<size_t>(L), w2 = static_cast<size_t>(n + p);
            return nb::make_tuple(to_numpy(std::move(r.dq)), to_numpy(std::move(r.status)),
                                  to_numpy(std::move(r.sigma)), to_numpy(std::move(r.lam2)),
                                  to_numpy(std::move(r.iterations)), to_numpy(std::move(r.active), {Ls, w2}),
                                  to_numpy(std::move(r.residuals)), to_numpy(std::move(r.certificate), {Ls, 4}),
                                  r.primal);
        },
        "A"_a, "b"_a, "w"_a, "starts"_a, "reg"_a, "lb"_a, "ub"_a, "G"_a, "h"_a, "threshold"_a, "max_damping"_a,
        "error_scale"_a, "rank_tol"_a, "max_iter"_a, "tol"_a, "warm"_a, "canonical"_a,
        "workspace"_a.none() = nb::none(), "lower_trust"_a = 0.0,
        "All levels of a hierarchy in one call: (dq, status, sigma, lam2, iterations, active, residuals, "
        "certificate (L, 4): primal, stationarity, dual, complementarity, primal at the final dq).");
}

// Bindings of the igm layer (qpik._engine.igm): the full-IK loop, its box QP, the
// SplitMix64 stream and the smallest singular value of a level.
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <memory>
#include <string>

#include "bind.hpp"
#include "bind_chain.hpp"
#include "igm/box_qp.hpp"
#include "igm/igm.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace qpik;
using namespace qpik::bind;

namespace {

using U64Out1 = Out<std::uint64_t, 1>;
using I64Out1 = Out<i64, 1>;
using I8Out1 = Out<i8, 1>;

template <class A>
A writable(nb::handle h, const char* what) {
    A out;
    if (!nb::try_cast(h, out, false))
        throw BadArgument(std::string(what) + " must be a writable C-contiguous array of the right dtype and dimensions");
    return out;
}

void check_box(const In2& H, const In1& g, const In1& lb, const In1& ub, const Out1& x) {
    size_t n = H.shape(0);
    require(H.shape(1) == n, "H must be square (n, n)");
    require(g.shape(0) == n && lb.shape(0) == n && ub.shape(0) == n && x.shape(0) == n,
            "g, lb, ub and x must be (n,) with H (n, n)");
}

nb::tuple box_qp_with(const In2& H, const In1& g, const In1& lb, const In1& ub, Out1& x, i64 max_iter,
                      const igm::BoxQPWork& w) {
    igm::BoxQPResult r = igm::box_qp(cmat(H), g.data(), lb.data(), ub.data(), x.data(), max_iter, w);
    return nb::make_tuple(r.status, r.iterations);
}

}  // namespace

// The argument checks igm_solve and igm_run share (shapes of the target, bounds, reach,
// options and RNG state), as ValueError in Python.
template <class T1, class T2, class B, class R, class O, class IO>
static void check_igm_shapes(const T1& target_p, const T2& target_R, const B& bounds, const R& reach,
                             const O& options, const IO& int_options, i64 nq) {
    require(target_p.shape(0) == 3, "target_p must be (3,)");
    require(target_R.shape(0) == 3 && target_R.shape(1) == 3, "target_R must be (3, 3)");
    require(bounds.shape(0) == 4 && static_cast<i64>(bounds.shape(1)) == nq, "bounds must be (4, nq)");
    require(reach.shape(0) == 4, "reach must be (4,)");
    require(options.shape(0) >= 11, "options must hold 11 or 12 floats");
    require(int_options.shape(0) == 4 || int_options.shape(0) == 5, "int_options must hold 4 or 5 ints");
}

template <class T1, class T2, class B, class R, class O, class IO, class S>
static void check_igm_args(const T1& target_p, const T2& target_R, const B& bounds, const R& reach,
                           const O& options, const IO& int_options, const S& rng_state, i64 nq) {
    check_igm_shapes(target_p, target_R, bounds, reach, options, int_options, nq);
    require(rng_state.shape(0) == 1, "rng_state must be a uint64 array of shape (1,)");
}

// The IGM's float options with entry 11 (the rank tolerance) present: 11 floats (the
// layout before it) read with 0 there, no structural cut (igm::structural_sigma);
// qpik.igm.kernels.kernel_options writes 12. buf: where such a copy is made.
static const double* igm_options(const double* options, i64 count, std::array<double, 12>& buf) {
    if (count >= 12) return options;
    std::copy(options, options + count, buf.begin());
    buf[11] = 0.0;
    return buf.data();
}

// igm_solve with its scratch allocated here (2 (max_iters + 1) iterates of nq and of 3, left
// uninitialised like np.empty: every entry read is written first), for igm_run and
// _igm_plan_run; the returned attempt is rec's slot info[3], info[4] rows long.
struct IgmScratch {
    std::unique_ptr<double[]> path, hist;
    igm::Record rec{};
    i64 info[6] = {};
};

// s's path and hist are (re)allocated unless already that size (an _IgmPlan's kept scratch);
// ws: igm_solve's workspace (nullptr: its own).
static void igm_with_scratch(IgmScratch& s, const model::Chain& c, const double* target_p, const double* target_R,
                             bool has_rot, const double* q0, i64 nq, CMatRef bounds, const double* reach,
                             const double* options, const i64* int_options, i64 budget, std::uint64_t& rng_state,
                             double deadline, igm::Workspace* ws = nullptr) {
    i64 max_iters = int_options[0];
    require(max_iters >= 0 && max_iters < (i64(1) << 40), "max_iters must be >= 0");
    igm::Target target{target_p, target_R, has_rot};
    i64 n = max_iters + 1;
    if (!s.path || s.rec.n != n || s.rec.nq != nq) {
        s.path.reset(new double[static_cast<size_t>(2 * n * nq)]);
        s.hist.reset(new double[static_cast<size_t>(2 * n * 3)]);
    }
    s.rec = igm::Record{s.path.get(), s.hist.get(), n, nq};
    igm::igm_solve(c, target, q0, nq, bounds, reach, options, int_options, budget, rng_state, deadline, s.rec, s.info,
                   ws);
}

static void igm_with_scratch(IgmScratch& s, nb::handle chain, In1 target_p, In2 target_R, nb::handle has_rot,
                             const double* q0, i64 nq, In2 bounds, In1 reach, In1 options, In<i64, 1> int_options,
                             std::uint64_t& rng_state, double deadline) {
    ChainArgs holder;
    const model::Chain& c = chain_arg(chain, nq, nq, holder);
    std::array<double, 12> buf{};
    igm_with_scratch(s, c, target_p.data(), target_R.data(), truthy(has_rot), q0, nq, cmat(bounds), reach.data(),
                     igm_options(options.data(), static_cast<i64>(options.shape(0)), buf), int_options.data(),
                     igm::iteration_budget(int_options.data(), static_cast<i64>(int_options.shape(0))), rng_state,
                     deadline);
}

// The chain's start q_full[index] (index null: all of q_full) into q0 (nq,).
static void gather_start(const double* q_full, i64 nfull, const i64* index, i64 nq, double* q0) {
    for (i64 j = 0; j < nq; ++j) {
        i64 a = index != nullptr ? index[j] : j;
        require(a >= 0 && a < nfull, "index entries must address q_full");
        q0[j] = q_full[a];
    }
}

// The tuple of _igm_plan_run from a finished run: the returned attempt's path as whole
// configurations (the coordinates off index as in q_full), its errors and history.
static nb::tuple session_tuple(const IgmScratch& run, const double* q_full, i64 nfull, const i64* index, i64 nq) {
    const igm::Record& rec = run.rec;
    const i64* info = run.info;
    i64 slot = info[3], length = info[4];
    size_t len = static_cast<size_t>(length), nf = static_cast<size_t>(nfull);
    std::vector<double> out_path(len * nf);
    for (i64 k = 0; k < length; ++k) {
        double* row = out_path.data() + k * nfull;
        const double* src = rec.path_at(slot, k);
        if (index != nullptr) {
            for (i64 j = 0; j < nfull; ++j) row[j] = q_full[j];
            for (i64 j = 0; j < nq; ++j) row[index[j]] = src[j];
        } else {
            for (i64 j = 0; j < nq; ++j) row[j] = src[j];
        }
    }
    std::vector<double> q_last(out_path.end() - nfull, out_path.end());
    const double* last = rec.hist_at(slot, length - 1);
    double position_error = last[0], orientation_error = last[1];
    std::vector<double> out_hist(rec.hist_at(slot, 0), rec.hist_at(slot, 0) + length * 3);
    return nb::make_tuple(info[0], info[1], info[2], to_numpy(std::move(q_last), {nf}),
                          to_numpy(std::move(out_path), {len, nf}), to_numpy(std::move(out_hist), {len, size_t(3)}),
                          position_error, orientation_error);
}

// What _igm_plan_run takes besides the target, the start, the RNG state and the
// deadline, checked and copied once (qpik._engine.igm._IgmPlan): an IKSession keeps one per
// (frame, limits, options), so that a solve converts six arguments instead of twelve.
struct IgmPlan {
    nb::object chain_ref;  // keeps the ChainData alive
    const model::Chain* chain = nullptr;
    i64 nfull = 0, nq = 0;
    bool packed = false;     // the chain's coordinates are q_full[index]; else all of q_full
    std::vector<i64> index;  // (nq,) when packed: empty for a frame no joint moves
    std::vector<double> bounds, reach, options;
    std::vector<i64> int_options;
    // The scratch of a run (igm_solve's workspace, the attempts' paths, the start), made by
    // the first run and reused by the next ones: a run's answer never depends on it (every
    // entry read is written first). busy: a run holds it (another run, on another thread,
    // makes its own).
    mutable std::unique_ptr<igm::Workspace> workspace;
    mutable IgmScratch scratch;
    mutable Vec start;
    mutable std::atomic<bool> busy{false};

    IgmPlan(nb::handle chain_obj, nb::handle index_obj, i64 nfull_, In2 bounds_, In1 reach_, In1 options_,
            In<i64, 1> int_options_) {
        require(nfull_ >= 0, "nfull must be >= 0");
        nfull = nfull_;
        packed = !index_obj.is_none();
        I64In1 idx;
        if (packed && !nb::try_cast(index_obj, idx, false))
            throw BadArgument("index must be None or an int64 array of chain coordinates");
        nq = packed ? static_cast<i64>(idx.shape(0)) : nfull;
        if (packed) {
            index.assign(idx.data(), idx.data() + nq);
            for (i64 a : index) require(a >= 0 && a < nfull, "index entries must address q_full");
        }
        ChainData* data = nullptr;
        if (!nb::try_cast<ChainData*>(chain_obj, data, false) || data == nullptr)
            throw BadArgument("chain must be a qpik._engine.model.Chain");
        chain = &data->fit(nq, nq);
        chain_ref = nb::borrow(chain_obj);
        require(bounds_.shape(0) == 4 && static_cast<i64>(bounds_.shape(1)) == nq, "bounds must be (4, nq)");
        require(reach_.shape(0) == 4, "reach must be (4,)");
        require(options_.shape(0) >= 11, "options must hold 11 or 12 floats");
        require(int_options_.shape(0) == 4 || int_options_.shape(0) == 5, "int_options must hold 4 or 5 ints");
        i64 max_iters = int_options_.data()[0];
        require(max_iters >= 0 && max_iters < (i64(1) << 40), "max_iters must be >= 0");
        bounds.assign(bounds_.data(), bounds_.data() + 4 * nq);
        reach.assign(reach_.data(), reach_.data() + 4);
        options.assign(options_.data(), options_.data() + options_.shape(0));
        if (options.size() < 12) options.resize(12, 0.0);  // (igm_options: no structural cut)
        int_options.assign(int_options_.data(), int_options_.data() + int_options_.shape(0));
    }
};

// A run's scratch: the plan's kept one when free (taken until this goes), else its own.
class PlanScratch {
  public:
    explicit PlanScratch(const IgmPlan& plan) : plan_(plan) {
        bool expected = false;
        held_ = plan.busy.compare_exchange_strong(expected, true);
        if (held_ && !plan.workspace) plan.workspace.reset(new igm::Workspace(*plan.chain, plan.nq));
        if (held_ && plan.start.size() != static_cast<size_t>(plan.nq)) plan.start.resize(static_cast<size_t>(plan.nq));
        if (!held_) own_start_.resize(static_cast<size_t>(plan.nq));
    }
    ~PlanScratch() {
        if (held_) plan_.busy.store(false);
    }
    PlanScratch(const PlanScratch&) = delete;
    PlanScratch& operator=(const PlanScratch&) = delete;
    Vec& start() { return held_ ? plan_.start : own_start_; }
    IgmScratch& run() { return held_ ? plan_.scratch : own_run_; }
    igm::Workspace* workspace() { return held_ ? plan_.workspace.get() : nullptr; }

  private:
    const IgmPlan& plan_;
    bool held_ = false;
    Vec own_start_;
    IgmScratch own_run_;
};

// The joint-limit box of a start, copied once (qpik._engine.igm._StartBox): check(q) is
// qpik._engine.model.start_defect(q, lower, upper, tol) with one array to convert a call.
struct StartBox {
    std::vector<double> lower, upper;
    double tol = 0.0;

    StartBox(In1 lower_, In1 upper_, double tol_) : tol(tol_) {
        require(lower_.shape(0) == upper_.shape(0), "lower and upper must have the same shape");
        lower.assign(lower_.data(), lower_.data() + lower_.shape(0));
        upper.assign(upper_.data(), upper_.data() + upper_.shape(0));
    }

    nb::tuple check(Out1 q) const {
        size_t n = q.shape(0);
        require(lower.size() == n, "q must be (n,) like lower and upper");
        return start_defect(q.data(), lower.data(), upper.data(), n, tol);
    }
};

// _target_ok's test of a (3,) position and (3, 3) rotation: the shapes, the position within
// max_distance of the origin (each coordinate; NaN fails) and the rotation orthonormal within
// orthonormal_tolerance (rotation_defect).
static bool target_pair_ok(const In1& p, const In2& R, double orthonormal_tolerance, double max_distance) {
    if (p.shape(0) != 3 || R.shape(0) != 3 || R.shape(1) != 3) return false;
    const double* pd = p.data();
    for (int i = 0; i < 3; ++i)
        if (!(std::fabs(pd[i]) <= max_distance)) return false;  // NaN too
    return model::rotation_defect(R.data()) <= orthonormal_tolerance;
}

// A plan's run from the whole configuration q_full (nfull,): its chain's start gathered, the
// IGM run in the plan's kept scratch, and _igm_plan_run's tuple.
static nb::tuple run_plan(const IgmPlan& plan, const double* target_p, const double* R, bool has_rot,
                          const double* q_full, std::uint64_t rng_state, double deadline) {
    // packed with no joint: index_p must still say packed (the coordinates off the chain,
    // all of them, as in q_full); an empty vector's data() may be null
    static const i64 none = 0;
    const i64* index_p = !plan.packed ? nullptr : plan.index.empty() ? &none : plan.index.data();
    PlanScratch held(plan);
    Vec& q0 = held.start();
    gather_start(q_full, plan.nfull, index_p, plan.nq, q0.data());
    igm_with_scratch(held.run(), *plan.chain, target_p, R, has_rot, q0.data(), plan.nq,
                     CMatRef(plan.bounds.data(), 4, plan.nq), plan.reach.data(), plan.options.data(),
                     plan.int_options.data(),
                     igm::iteration_budget(plan.int_options.data(), static_cast<i64>(plan.int_options.size())),
                     rng_state, deadline, held.workspace());
    return session_tuple(held.run(), q_full, plan.nfull, index_p, plan.nq);
}

// _igm_lean_run's tests of a target (position, rotation) and a start q_obj for plan: float64
// C-contiguous arrays of the shapes it takes, target_pair_ok, and the start within box
// (start_defect_code, which clips it into q_full, a copy); false where one fails.
static bool lean_inputs(const IgmPlan& plan, nb::handle position, nb::handle rotation, nb::handle q_obj,
                        const StartBox& box, double orthonormal_tolerance, double max_distance, In1& p, In2& R,
                        Vec& q_full) {
    In1 q;
    if (!nb::try_cast(position, p, false) || !nb::try_cast(rotation, R, false) || !nb::try_cast(q_obj, q, false))
        return false;
    if (!target_pair_ok(p, R, orthonormal_tolerance, max_distance)) return false;
    size_t n = q.shape(0);
    if (static_cast<i64>(n) != plan.nfull || box.lower.size() != n) return false;
    q_full.assign(q.data(), q.data() + n);
    i64 index;
    return start_defect_code(q_full.data(), box.lower.data(), box.upper.data(), n, box.tol, index) == 0;
}

// IKSession's lean solve in one compiled call (qpik.igm.session.IKSession._solve's lane):
// the options memo's test, _lean's tests, the draw of the restarts' RNG state, the run and
// _compiled_result's IKResult, with no Python frame between the call and the engine (a solve
// between a planner's other work runs with cold caches, where the interpreter's frames and
// its objects' lines cost several times what the run's first iterations do). Made by the
// session for its options memo (memo: base, keywords, settings, kernel options, keys, types,
// lean), for that memo only. solve() answers None, having drawn nothing and run nothing,
// wherever any test fails: the general path then answers (or raises) as it always did.
struct SessionLane {
    nb::object base, memo_kw, kernel_options, frames, box_obj, budget, mid, seed_default;
    const StartBox* box = nullptr;
    // (IKResult, LazyRows, the reasons by code, Generator, the raw-uint64 bit generators,
    // rng_state, time.perf_counter, list, tuple)
    nb::object result_type, rows_type, reasons, generator, raw_types, rng_state, perf_counter, list_type,
        tuple_type;
    double orthonormal_tolerance = 0.0, max_distance = 0.0;
    nb::object hist_columns, error_columns, engine;  // slice(2, None), slice(0, 2), "compiled"
    nb::object k_q0, k_seed, k_stack, a_plan, a_name, a_bit_generator, a_random_raw;
    std::array<nb::object, 16> fields;  // IKResult's fields in its __init__'s order
    std::array<nb::object, 4> slot_set;  // LazyRows's slots' member descriptors
    nb::object empty;                   // ()

    SessionLane(nb::handle base_, nb::dict memo_kw_, nb::handle kernel_options_, nb::dict frames_,
                nb::handle box_, nb::handle budget_, nb::handle mid_, nb::handle seed_default_, nb::tuple consts,
                double orthonormal_tolerance_, double max_distance_)
        : base(nb::borrow(base_)), memo_kw(memo_kw_), kernel_options(nb::borrow(kernel_options_)),
          frames(frames_), box_obj(nb::borrow(box_)), budget(nb::borrow(budget_)), mid(nb::borrow(mid_)),
          seed_default(nb::borrow(seed_default_)), orthonormal_tolerance(orthonormal_tolerance_),
          max_distance(max_distance_) {
        require(consts.size() == 9, "consts must be (IKResult, LazyRows, reasons, Generator, raw types, "
                                    "rng_state, perf_counter, list, tuple)");
        box = &nb::cast<const StartBox&>(box_obj);
        require(budget.is_none() || PyFloat_CheckExact(budget.ptr()), "budget must be None or a float");
        result_type = consts[0];
        rows_type = consts[1];
        reasons = consts[2];
        generator = consts[3];
        raw_types = consts[4];
        rng_state = consts[5];
        perf_counter = consts[6];
        list_type = consts[7];
        tuple_type = consts[8];
        require(PyType_Check(result_type.ptr()) && PyType_Check(rows_type.ptr()) && PyTuple_Check(reasons.ptr()) &&
                    PyTuple_Check(raw_types.ptr()),
                "consts: IKResult and LazyRows must be types, reasons and raw types tuples");
        hist_columns = nb::steal(PySlice_New(nb::int_(2).ptr(), Py_None, nullptr));
        error_columns = nb::steal(PySlice_New(nb::int_(0).ptr(), nb::int_(2).ptr(), nullptr));
        engine = intern("compiled");
        k_q0 = intern("q0");
        k_seed = intern("seed");
        k_stack = intern("stack");
        a_plan = intern("plan");
        a_name = intern("name");
        a_bit_generator = intern("bit_generator");
        a_random_raw = intern("random_raw");
        empty = nb::steal(PyTuple_New(0));
        static const char* slots[4] = {"_array", "_kind", "_first", "_columns"};
        for (size_t i = 0; i < 4; ++i) {
            // (the slot's member descriptor in LazyRows's own dict)
            PyObject* d = PyDict_GetItemString(reinterpret_cast<PyTypeObject*>(rows_type.ptr())->tp_dict, slots[i]);
            require(d != nullptr && Py_TYPE(d)->tp_descr_set != nullptr, "LazyRows must have its four slots");
            slot_set[i] = nb::borrow(d);
        }
        static const char* names[16] = {"q", "converged", "reason", "iterations", "restarts_used",
                                        "position_error", "orientation_error", "solve_time", "frame_errors",
                                        "residual_history", "error_history", "path", "engine", "levels_met",
                                        "coupling_error", "constraint_error"};
        for (int i = 0; i < 16; ++i) fields[static_cast<size_t>(i)] = intern(names[i]);
    }

    static nb::object intern(const char* s) { return nb::steal(PyUnicode_InternFromString(s)); }

    // Whether key is the interned special name k (the same string: identity, else equality).
    static bool is_key(PyObject* key, const nb::object& k) {
        return key == k.ptr() || (PyUnicode_CheckExact(key) && PyUnicode_Compare(key, k.ptr()) == 0);
    }

    // A LazyRows(history, kind, first, start, stop) with the slots its __init__ sets, each
    // stored through its member descriptor (slot_set: LazyRows._array, ._kind, ._first,
    // ._columns, looked up once).
    nb::object rows(nb::handle history, nb::handle kind, long first, const nb::object& columns) const {
        nb::object r = nb::steal(PyBaseObject_Type.tp_new(reinterpret_cast<PyTypeObject*>(rows_type.ptr()),
                                                          empty.ptr(), nullptr));
        if (!r.is_valid()) throw nb::python_error();
        nb::object f = nb::int_(first);
        PyObject* values[4] = {history.ptr(), kind.ptr(), f.ptr(), columns.ptr()};
        for (size_t i = 0; i < 4; ++i) {
            PyObject* d = slot_set[i].ptr();
            if (Py_TYPE(d)->tp_descr_set(d, r.ptr(), values[i])) throw nb::python_error();
        }
        return r;
    }

    // The keywords (**keywords of the solve) against the memo, q0, seed and stack aside
    // (_options's test: the same keys, each value equal and of the same type); false where
    // they differ or a comparison raises (the general path compares again).
    bool keywords_match(PyObject* kw, PyObject** q0, PyObject** seed) const {
        Py_ssize_t pos = 0, matched = 0;
        PyObject *key, *value;
        while (PyDict_Next(kw, &pos, &key, &value)) {
            if (is_key(key, k_q0)) {
                *q0 = value;
                continue;
            }
            if (is_key(key, k_seed)) {
                *seed = value;
                continue;
            }
            if (is_key(key, k_stack)) {
                if (value != Py_None) return false;
                continue;
            }
            PyObject* kept = PyDict_GetItemWithError(memo_kw.ptr(), key);
            if (kept == nullptr || Py_TYPE(kept) != Py_TYPE(value)) {
                PyErr_Clear();
                return false;
            }
            int equal = PyObject_RichCompareBool(value, kept, Py_EQ);
            if (equal != 1) {
                PyErr_Clear();
                return false;
            }
            ++matched;
        }
        return matched == PyDict_GET_SIZE(memo_kw.ptr());
    }

    // The restarts' RNG state of the solve (_solve's draw): one draw from a Generator over a
    // raw-uint64 bit generator, else rng_state(seed), settings.seed where none was given.
    // false (nothing drawn) where rng_state raises: the general path raises it.
    bool draw(PyObject* seed, std::uint64_t& state) const {
        nb::object drawn;
        if (seed != nullptr && Py_TYPE(seed) == reinterpret_cast<PyTypeObject*>(generator.ptr())) {
            nb::object bits = nb::steal(PyObject_GetAttr(seed, a_bit_generator.ptr()));
            if (!bits.is_valid()) throw nb::python_error();
            int raw = PySequence_Contains(raw_types.ptr(), reinterpret_cast<PyObject*>(Py_TYPE(bits.ptr())));
            if (raw < 0) throw nb::python_error();
            if (raw) {
                drawn = nb::steal(PyObject_CallMethodNoArgs(bits.ptr(), a_random_raw.ptr()));
                if (!drawn.is_valid()) throw nb::python_error();
            }
        }
        if (!drawn.is_valid()) {
            PyObject* arg = seed == nullptr ? seed_default.ptr() : seed;
            drawn = nb::steal(PyObject_CallOneArg(rng_state.ptr(), arg));
            if (!drawn.is_valid()) {
                PyErr_Clear();
                return false;
            }
        }
        state = PyLong_AsUnsignedLongLong(drawn.ptr());
        if (state == static_cast<std::uint64_t>(-1) && PyErr_Occurred()) throw nb::python_error();
        return true;
    }

    nb::object solve(nb::handle defaults, nb::handle robot_q, nb::handle targets, nb::handle keywords,
                     double start_time) const {
        if (!defaults.is(base) || !PyDict_CheckExact(targets.ptr()) || PyDict_GET_SIZE(targets.ptr()) != 1 ||
            !PyDict_CheckExact(keywords.ptr()))
            return nb::none();
        PyObject *q0 = nullptr, *seed = nullptr;
        if (!keywords_match(keywords.ptr(), &q0, &seed)) return nb::none();
        // _lean: one (position, rotation) target of a frame whose plan has these options
        Py_ssize_t pos = 0;
        PyObject *key, *value;
        PyDict_Next(targets.ptr(), &pos, &key, &value);
        // (strong references: the calls into Python below may change the dicts they came from)
        const nb::object value_ref = nb::borrow(value);
        PyObject* frame = PyDict_GetItemWithError(frames.ptr(), key);
        if (frame == nullptr) {
            PyErr_Clear();  // (an unhashable key)
            return nb::none();
        }
        const nb::object frame_ref = nb::borrow(frame);
        if (!PyTuple_CheckExact(value) || PyTuple_GET_SIZE(value) != 2) return nb::none();
        nb::object plan = nb::steal(PyObject_GetAttr(frame, a_plan.ptr()));
        if (!plan.is_valid()) throw nb::python_error();
        if (!PyTuple_CheckExact(plan.ptr()) || PyTuple_GET_SIZE(plan.ptr()) != 4 ||
            PyTuple_GET_ITEM(plan.ptr(), 0) != kernel_options.ptr() || PyTuple_GET_ITEM(plan.ptr(), 1) != Py_True)
            return nb::none();
        const IgmPlan* compiled = nullptr;
        if (!nb::try_cast(nb::handle(PyTuple_GET_ITEM(plan.ptr(), 3)), compiled, false) || compiled == nullptr)
            return nb::none();
        if (q0 == nullptr || q0 == Py_None) q0 = robot_q.is_none() ? mid.ptr() : robot_q.ptr();
        const nb::object q0_ref = nb::borrow(q0), seed_ref = nb::borrow(seed);
        int timed = PyObject_IsTrue(PyTuple_GET_ITEM(plan.ptr(), 2));
        if (timed < 0) throw nb::python_error();
        const double deadline = timed && !budget.is_none() ? start_time + PyFloat_AS_DOUBLE(budget.ptr()) : kInf;
        // igm_lean_run's tests, then the draw and the run
        In1 p;
        In2 R;
        Vec q_full;
        if (!lean_inputs(*compiled, PyTuple_GET_ITEM(value, 0), PyTuple_GET_ITEM(value, 1), q0, *box,
                         orthonormal_tolerance, max_distance, p, R, q_full))
            return nb::none();
        std::uint64_t state = 0;
        if (!draw(seed, state)) return nb::none();
        nb::tuple run = run_plan(*compiled, p.data(), R.data(), true, q_full.data(), state, deadline);
        // _compiled_result(run, frame.name, start_time, 0.0)
        nb::object name = nb::steal(PyObject_GetAttr(frame, a_name.ptr()));
        if (!name.is_valid()) throw nb::python_error();
        const i64 code = nb::cast<i64>(run[0]);
        const bool converged = code == 0;
        require(code >= 0 && code < static_cast<i64>(PyTuple_GET_SIZE(reasons.ptr())), "unknown reason code");
        nb::object now = nb::steal(PyObject_CallNoArgs(perf_counter.ptr()));
        if (!now.is_valid()) throw nb::python_error();
        nb::object solve_time = nb::float_(PyFloat_AsDouble(now.ptr()) - start_time);
        nb::object errors = nb::make_tuple(run[6], run[7]);
        nb::dict frame_errors;
        frame_errors[name] = errors;
        nb::object history = run[5];
        nb::object zero = nb::float_(0.0);
        nb::object values[16] = {run[3],
                                 nb::borrow(converged ? Py_True : Py_False),
                                 nb::borrow(PyTuple_GET_ITEM(reasons.ptr(), code)),
                                 run[1],
                                 run[2],
                                 run[6],
                                 run[7],
                                 solve_time,
                                 frame_errors,
                                 rows(history, list_type, 1, hist_columns),
                                 rows(history, tuple_type, 0, error_columns),
                                 run[4],
                                 engine,
                                 nb::make_tuple(nb::borrow(converged ? Py_True : Py_False)),
                                 zero,
                                 zero};
        // The instance's attributes as one dict, given as its __dict__ (no per-field lookup
        // of the class's descriptors: a dataclass has none for its fields).
        nb::object result = nb::steal(PyBaseObject_Type.tp_new(reinterpret_cast<PyTypeObject*>(result_type.ptr()),
                                                               empty.ptr(), nullptr));
        if (!result.is_valid()) throw nb::python_error();
        nb::object attributes = nb::steal(_PyDict_NewPresized(16));
        if (!attributes.is_valid()) throw nb::python_error();
        for (size_t i = 0; i < 16; ++i)
            if (PyDict_SetItem(attributes.ptr(), fields[i].ptr(), values[i].ptr())) throw nb::python_error();
        if (PyObject_GenericSetDict(result.ptr(), attributes.ptr(), nullptr)) throw nb::python_error();
        return result;
    }
};

void bind_igm(nb::module_& m) {
    m.attr("CONVERGED") = igm::CONVERGED;
    m.attr("MAX_ITERS") = igm::MAX_ITERS;
    m.attr("TIME_BUDGET") = igm::TIME_BUDGET;
    m.attr("STALLED") = igm::STALLED;
    m.attr("AT_LIMIT") = igm::AT_LIMIT;
    m.attr("SINGULAR") = igm::SINGULAR;
    m.attr("UNREACHABLE") = igm::UNREACHABLE;
    m.attr("BACKTRACKS") = igm::BACKTRACKS;
    m.attr("PROGRESS") = igm::PROGRESS;
    m.attr("CLOCK_EVERY") = igm::CLOCK_EVERY;
    m.attr("RESTART_SPREAD") = igm::RESTART_SPREAD;
    m.attr("BLOCKED") = igm::BLOCKED;
    m.attr("NEAR_TARGET") = igm::NEAR_TARGET;

    m.def(
        "box_qp",
        [](In2 H, In1 g, In1 lb, In1 ub, Out1 x, i64 max_iter) {
            check_box(H, g, lb, ub, x);
            igm::BoxQPScratch scratch(static_cast<i64>(H.shape(0)));
            return box_qp_with(H, g, lb, ub, x, max_iter, scratch.work());
        },
        "H"_a, "g"_a, "lb"_a, "ub"_a, "x"_a.noconvert(), "max_iter"_a,
        "min 1/2 x^T H x + g^T x s.t. lb <= x <= ub (H positive definite) by a primal active-set "
        "method; the minimiser into x; returns (status, iterations): 0 solved, 1 the cap, 2 H not "
        "positive definite.");

    m.def(
        "_box_qp",
        [](In2 H, In1 g, In1 lb, In1 ub, Out1 x, i64 max_iter, nb::handle workspace) {
            check_box(H, g, lb, ub, x);
            require(nb::isinstance<nb::tuple>(workspace) && nb::len(workspace) == 6,
                    "workspace must be the tuple of _box_qp_workspace(n)");
            nb::tuple t = nb::borrow<nb::tuple>(workspace);
            auto state = writable<I8Out1>(t[0], "workspace[0] (int8 state)");
            auto free = writable<I64Out1>(t[1], "workspace[1] (int64 free)");
            auto L = writable<Out2>(t[2], "workspace[2] (float64 L)");
            auto target = writable<Out1>(t[3], "workspace[3] (float64 target)");
            auto rhs = writable<Out1>(t[4], "workspace[4] (float64 rhs)");
            auto y = writable<Out1>(t[5], "workspace[5] (float64 y)");
            size_t n = H.shape(0);
            require(state.shape(0) >= n && free.shape(0) >= n && L.shape(0) >= n && L.shape(1) >= n &&
                        target.shape(0) >= n && rhs.shape(0) >= n && y.shape(0) >= n,
                    "workspace arrays too small for n variables");
            igm::BoxQPWork w{state.data(), free.data(), mat(L), target.data(), rhs.data(), y.data()};
            return box_qp_with(H, g, lb, ub, x, max_iter, w);
        },
        "H"_a, "g"_a, "lb"_a, "ub"_a, "x"_a.noconvert(), "max_iter"_a, "workspace"_a,
        "box_qp with its scratch (_box_qp_workspace(n)) given.");

    m.def(
        "uniform",
        [](U64Out1 state) {
            require(state.shape(0) == 1, "state must be a uint64 array of shape (1,)");
            return igm::uniform(state.data()[0]);
        },
        "state"_a.noconvert(),
        "A uniform draw in [0, 1) from the SplitMix64 stream state (uint64 (1,), advanced in place).");

    m.def(
        "_smallest_singular_value",
        [](In2 A, i64 m, i64 nv, Out2 G, double threshold) {
            require(m >= 0 && m <= static_cast<i64>(A.shape(0)), "m must be in [0, A.shape[0]]");
            require(nv >= 0 && nv <= static_cast<i64>(A.shape(1)), "nv must be in [0, A.shape[1]]");
            i64 need = std::min(m, nv);
            require(static_cast<i64>(G.shape(0)) >= need && static_cast<i64>(G.shape(1)) >= need,
                    "G must be at least (min(m, nv), min(m, nv))");
            i64 n = std::max<i64>(6, nv);
            IVec rows(static_cast<size_t>(std::max<i64>(m, 1)));
            Mat L(n, n);
            return igm::smallest_singular_value_in(cmat(A), m, nv, mat(G), threshold, rows.data(), L.ref());
        },
        "A"_a, "m"_a, "nv"_a, "G"_a.noconvert(), "threshold"_a = 0.0,
        "The min(r, nv)-th singular value of A[:m] (r: its rows not identically zero), from the "
        "Gram matrix built in G; with threshold > 0, inf when it is at least threshold.");

    m.def(
        "igm_solve",
        [](nb::handle chain, In1 target_p, In2 target_R, nb::handle has_rot, In1 q0, In2 bounds, In1 reach,
           In1 options, In<i64, 1> int_options, U64Out1 rng_state, double deadline, Out3 path, Out3 hist,
           I64Out1 info) {
            i64 nq = static_cast<i64>(q0.shape(0));
            check_igm_args(target_p, target_R, bounds, reach, options, int_options, rng_state, nq);
            require(info.shape(0) == 6, "info must be int64 (6,)");
            i64 max_iters = int_options.data()[0];
            require(max_iters >= 0, "max_iters must be >= 0");
            require(path.shape(0) == 2 && static_cast<i64>(path.shape(1)) >= max_iters + 1 &&
                        static_cast<i64>(path.shape(2)) == nq,
                    "path must be (2, max_iters + 1, nq)");
            require(hist.shape(0) == 2 && hist.shape(1) == path.shape(1) && hist.shape(2) == 3,
                    "hist must be (2, max_iters + 1, 3)");
            ChainArgs holder;
            const model::Chain& c = chain_arg(chain, nq, nq, holder);
            igm::Target target{target_p.data(), target_R.data(), truthy(has_rot)};
            igm::Record rec{path.data(), hist.data(), static_cast<i64>(path.shape(1)), nq};
            std::array<double, 12> buf{};
            igm::igm_solve(c, target, q0.data(), nq, cmat(bounds), reach.data(),
                           igm_options(options.data(), static_cast<i64>(options.shape(0)), buf), int_options.data(),
                           igm::iteration_budget(int_options.data(), static_cast<i64>(int_options.shape(0))),
                           rng_state.data()[0], deadline, rec, info.data());
        },
        "chain"_a, "target_p"_a, "target_R"_a, "has_rot"_a, "q0"_a, "bounds"_a, "reach"_a, "options"_a,
        "int_options"_a, "rng_state"_a.noconvert(), "deadline"_a, "path"_a.noconvert(), "hist"_a.noconvert(),
        "info"_a.noconvert(),
        "The whole IGM solve of one frame target (see qpik.igm.kernels.igm_solve); writes path, "
        "hist and info and advances rng_state in place.");

    m.def(
        "igm_run",
        [](nb::handle chain, In1 target_p, In2 target_R, nb::handle has_rot, In1 q0, In2 bounds, In1 reach,
           In1 options, In<i64, 1> int_options, U64Out1 rng_state, double deadline) {
            i64 nq = static_cast<i64>(q0.shape(0));
            check_igm_args(target_p, target_R, bounds, reach, options, int_options, rng_state, nq);
            IgmScratch run;
            igm_with_scratch(run, chain, target_p, target_R, has_rot, q0.data(), nq, bounds, reach, options,
                             int_options, rng_state.data()[0], deadline);
            const igm::Record& rec = run.rec;
            const i64* info = run.info;
            i64 slot = info[3], length = info[4];
            std::vector<double> out_path(rec.path_at(slot, 0), rec.path_at(slot, 0) + length * nq);
            std::vector<double> out_hist(rec.hist_at(slot, 0), rec.hist_at(slot, 0) + length * 3);
            size_t len = static_cast<size_t>(length), nqs = static_cast<size_t>(nq);
            return nb::make_tuple(info[0], info[1], info[2], to_numpy(std::move(out_path), {len, nqs}),
                                  to_numpy(std::move(out_hist), {len, size_t(3)}));
        },
        "chain"_a, "target_p"_a, "target_R"_a, "has_rot"_a, "q0"_a, "bounds"_a, "reach"_a, "options"_a,
        "int_options"_a, "rng_state"_a.noconvert(), "deadline"_a,
        "igm_solve with its scratch allocated here: returns (reason code, iterations, restarts used, "
        "path (k, nq), hist (k, 3)) of the returned attempt (its iterates, start first; per iterate "
        "position error [m], orientation error [rad] and the residual of the step that left it).");

    nb::class_<IgmPlan>(m, "_IgmPlan",
                        "The fixed arguments of _igm_plan_run (chain, index, bounds, reach, options, "
                        "int_options), checked and copied once.")
        .def(nb::init<nb::handle, nb::handle, i64, In2, In1, In1, In<i64, 1>>(), "chain"_a, "index"_a.none(),
             "nfull"_a, "bounds"_a, "reach"_a, "options"_a, "int_options"_a,
             "Check and copy the arguments of _igm_plan_run that do not change between solves "
             "(chain: a qpik._engine.model.Chain over the coordinates index of configurations of "
             "nfull coordinates; index None: all of them).")
        .def_ro("nfull", &IgmPlan::nfull, "Coordinates of the whole configuration.");

    m.def(
        "_igm_plan_run",
        [](const IgmPlan& plan, In1 target_p, nb::handle target_R, In1 q_full, std::uint64_t rng_state,
           double deadline) {
            require(target_p.shape(0) == 3, "target_p must be (3,)");
            require(static_cast<i64>(q_full.shape(0)) == plan.nfull, "q_full must be (nfull,)");
            static const double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
            const double* R = eye;
            In2 rot;
            bool has_rot = !target_R.is_none();
            if (has_rot) {
                if (!nb::try_cast(target_R, rot, true))
                    throw BadArgument("target_R must be None or a float64 (3, 3) array");
                require(rot.shape(0) == 3 && rot.shape(1) == 3, "target_R must be (3, 3)");
                R = rot.data();
            }
            return run_plan(plan, target_p.data(), R, has_rot, q_full.data(), rng_state, deadline);
        },
        "plan"_a, "target_p"_a, "target_R"_a.none(), "q_full"_a, "rng_state"_a, "deadline"_a,
        "igm_run on the coordinates plan.index of q_full (None: all of them) with the fixed "
        "arguments in plan (an _IgmPlan), from the SplitMix64 state rng_state (an int in "
        "[0, 2**64); not written back); target_R None: a position-only target. Returns "
        "(reason code, iterations, restarts used, q (the answer, a whole configuration), path "
        "(k, len(q_full)), hist (k, 3), position error [m], orientation error [rad]).");

    m.def(
        "_igm_lean_run",
        [](const IgmPlan& plan, nb::handle position, nb::handle rotation, nb::handle q_obj, const StartBox& box,
           std::uint64_t rng_state, double deadline, double orthonormal_tolerance,
           double max_distance) -> nb::object {
            // IKSession's common solve in one call: _target_ok's target, the start checked and
            // clipped as _StartBox.check does (into a copy: q_obj is not written), then
            // _igm_plan_run on the whole configuration. Anything else (another dtype or shape,
            // a target or start _target_ok or check would not pass): None, nothing run, and the
            // session's general path answers (or raises) as it always did.
            In1 p;
            In2 R;
            Vec q_full;
            if (!lean_inputs(plan, position, rotation, q_obj, box, orthonormal_tolerance, max_distance, p, R, q_full))
                return nb::none();
            return run_plan(plan, p.data(), R.data(), true, q_full.data(), rng_state, deadline);
        },
        "plan"_a, "position"_a, "rotation"_a, "q"_a, "start_box"_a, "rng_state"_a, "deadline"_a,
        "orthonormal_tolerance"_a, "max_distance"_a,
        "_igm_plan_run of a (position, rotation) target on the start q (a float64 (nfull,) array, "
        "checked against start_box and clipped into it in a copy, as _StartBox.check does) when "
        "_target_ok(position, rotation, orthonormal_tolerance, max_distance) holds and the start "
        "passes the check; else None (nothing run).");

    m.def(
        "_target_ok",
        [](nb::handle position, nb::handle rotation, double orthonormal_tolerance, double max_distance) {
            // The common target of parse_target in one call: float64 C-contiguous arrays (3,)
            // and (3, 3), finite, the rotation orthonormal within orthonormal_tolerance
            // (rotation_defect) and the position within max_distance of the origin. Anything
            // else: false (parse_target's general path decides).
            In1 p;
            In2 R;
            if (!nb::try_cast(position, p, false) || !nb::try_cast(rotation, R, false)) return false;
            return target_pair_ok(p, R, orthonormal_tolerance, max_distance);
        },
        "position"_a, "rotation"_a, "orthonormal_tolerance"_a, "max_distance"_a,
        "Whether (position, rotation) are float64 C-contiguous (3,) and (3, 3) arrays, finite, the "
        "rotation orthonormal within orthonormal_tolerance and the position within max_distance of "
        "the origin (each coordinate).");

    nb::class_<SessionLane>(m, "_SessionLane",
                            "IKSession's lean solve in one call, for one options memo (see "
                            "qpik.igm.session.IKSession._solve).")
        .def(nb::init<nb::handle, nb::dict, nb::handle, nb::dict, nb::handle, nb::handle, nb::handle, nb::handle,
                      nb::tuple, double, double>(),
             "base"_a, "memo_keywords"_a, "kernel_options"_a, "frames"_a, "start_box"_a, "budget"_a.none(),
             "mid"_a, "seed"_a.none(), "consts"_a, "orthonormal_tolerance"_a, "max_distance"_a)
        .def("solve", &SessionLane::solve, "defaults"_a, "robot_q"_a.none(), "targets"_a, "keywords"_a,
             "start_time"_a,
             "The solve's IKResult, or None (nothing drawn, nothing run) where the general path must "
             "answer.");

    nb::class_<StartBox>(m, "_StartBox",
                         "A start's joint-limit box (lower, upper, tol), copied once; check(q) is "
                         "qpik._engine.model.start_defect(q, lower, upper, tol).")
        .def(nb::init<In1, In1, double>(), "lower"_a, "upper"_a, "tol"_a)
        .def("check", &StartBox::check, "q"_a.noconvert(),
             "(1, i) for the first entry of q not finite, (2, i) for the first outside [lower - tol, "
             "upper + tol], else (0, -1) with q clipped into [lower, upper] in place.");
}

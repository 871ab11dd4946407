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
            In1 p, q;
            In2 R;
            if (!nb::try_cast(position, p, false) || !nb::try_cast(rotation, R, false) ||
                !nb::try_cast(q_obj, q, false))
                return nb::none();
            if (!target_pair_ok(p, R, orthonormal_tolerance, max_distance)) return nb::none();
            size_t n = q.shape(0);
            if (static_cast<i64>(n) != plan.nfull || box.lower.size() != n) return nb::none();
            Vec q_full(q.data(), q.data() + n);
            i64 index;
            if (start_defect_code(q_full.data(), box.lower.data(), box.upper.data(), n, box.tol, index) != 0)
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

    nb::class_<StartBox>(m, "_StartBox",
                         "A start's joint-limit box (lower, upper, tol), copied once; check(q) is "
                         "qpik._engine.model.start_defect(q, lower, upper, tol).")
        .def(nb::init<In1, In1, double>(), "lower"_a, "upper"_a, "tol"_a)
        .def("check", &StartBox::check, "q"_a.noconvert(),
             "(1, i) for the first entry of q not finite, (2, i) for the first outside [lower - tol, "
             "upper + tol], else (0, -1) with q clipped into [lower, upper] in place.");
}

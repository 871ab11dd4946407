// Bindings of the diffik layer (qpik._engine.diffik): the one-call IK step (diffik/fused.hpp,
// used by qpik.diffik.compiled). Every shape and index is checked here (a bad plan raises ValueError, never
// reads out of bounds); the plan's and MuJoCo's arrays are used in place (no copies).
#include "bind.hpp"
#include "bind_tree.hpp"
#include "diffik/fused.hpp"
#include "model/com.hpp"
#include "model/jac.hpp"

#include <nanobind/stl/optional.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <tuple>

namespace nb = nanobind;
using namespace qpik;
using namespace qpik::bind;

namespace {

using I1 = nb::ndarray<const i64, nb::numpy, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using I2 = nb::ndarray<const i64, nb::numpy, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using Int32In1 = nb::ndarray<const std::int32_t, nb::numpy, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using B2 = nb::ndarray<const i8, nb::numpy, nb::ndim<2>, nb::c_contig, nb::device::cpu>;

template <class X>
i64 dim(const X& x, size_t k) { return static_cast<i64>(x.shape(k)); }

VecRefT<const i64> ivec(const I1& x) { return VecRefT<const i64>(x.data(), dim(x, 0)); }
MatRefT<const i64> imat(const I2& x) { return MatRefT<const i64>(x.data(), dim(x, 0), dim(x, 1)); }

void check_dofs(VecRefT<const i64> dofs, i64 n, const char* what) {
    for (i64 e = 0; e < dofs.n; ++e) require(dofs[e] >= 0 && dofs[e] < n, what);
}

// The views of fused_rows' / fused_step's arguments, after checking every shape and index.
diffik::FusedArgs make_args(Out2& A, Out1& b, Out1& w, const I1& starts, const I2& tasks,
                            const In3& jac, const I2& frames, const In2& site_xpos,
                            const In2& site_xmat, const In2& xpos, const In2& xmat,
                            const In2& geom_xpos, const In2& geom_xmat, const In2& frame_data,
                            const In1& qpos, const In2& posture_data, const I1& cfg_dof,
                            const In2& cfg_data, const I1& vel_dof, const In1& vel_limit,
                            const In1& settings) {
    const i64 n = dim(qpos, 0);
    const i64 M = dim(A, 0);
    require(dim(A, 1) == n, "fused: A must have shape (M, nv) with nv = len(qpos)");
    require(dim(b, 0) == M && dim(w, 0) == M, "fused: b and w must have shape (M,)");
    const i64 L = dim(starts, 0) - 1;
    require(L >= 0, "fused: starts must have L + 1 >= 1 entries");
    const i64* s = starts.data();
    require(s[0] == 0 && s[L] == M, "fused: starts must run from 0 to M");
    for (i64 k = 0; k < L; ++k) require(s[k] <= s[k + 1], "fused: starts must not decrease");
    const i64 F = dim(frames, 0), P = dim(posture_data, 0);
    require(dim(frames, 1) == 2, "fused: frames must have shape (F, 2)");
    require(dim(jac, 0) == F && dim(jac, 1) == 6 && dim(jac, 2) == n,
            "fused: jac must have shape (F, 6, nv)");
    require(dim(frame_data, 0) == F && dim(frame_data, 1) == diffik::kFrameData,
            "fused: frame_data must have shape (F, 15)");
    require(dim(posture_data, 1) >= 2 * n + 2, "fused: posture_data must have shape (P, nq + nv + 2)");
    require(dim(site_xpos, 1) == 3 && dim(xpos, 1) == 3 && dim(geom_xpos, 1) == 3,
            "fused: the positions must have shape (*, 3)");
    require(dim(site_xmat, 1) == 9 && dim(xmat, 1) == 9 && dim(geom_xmat, 1) == 9,
            "fused: the rotations must have shape (*, 9)");
    const i64 count[3] = {std::min(dim(site_xpos, 0), dim(site_xmat, 0)),
                          std::min(dim(xpos, 0), dim(xmat, 0)),
                          std::min(dim(geom_xpos, 0), dim(geom_xmat, 0))};
    const i64* fr = frames.data();
    for (i64 f = 0; f < F; ++f) {
        const i64 kind = fr[2 * f], fid = fr[2 * f + 1];
        require(kind >= 0 && kind <= 2, "fused: a frame kind is not 0 (site), 1 (body) or 2 (geom)");
        require(fid >= 0 && fid < count[kind], "fused: a frame id is out of range of its poses");
    }
    require(dim(tasks, 1) == 4, "fused: tasks must have shape (T, 4)");
    const i64* t = tasks.data();
    for (i64 k = 0; k < dim(tasks, 0); ++k) {
        const i64 kind = t[4 * k], index = t[4 * k + 1], level = t[4 * k + 2], row = t[4 * k + 3];
        require(kind == 0 || kind == 1, "fused: a task kind is not 0 (frame) or 1 (posture)");
        require(index >= 0 && index < (kind == 0 ? F : P), "fused: a task index is out of range");
        require(level >= 0 && level < L, "fused: a task level is out of range");
        const i64 size = kind == 0 ? 6 : n;
        require(row >= 0 && row + size <= M, "fused: a task's rows are out of range of A");
    }
    require(dim(cfg_data, 0) == dim(cfg_dof, 0) && dim(cfg_data, 1) == 3,
            "fused: cfg_data must have shape (len(cfg_dof), 3)");
    check_dofs(ivec(cfg_dof), n, "fused: a cfg_dof entry is out of range");
    require(dim(vel_limit, 0) == dim(vel_dof, 0), "fused: vel_limit must have len(vel_dof) entries");
    check_dofs(ivec(vel_dof), n, "fused: a vel_dof entry is out of range");
    require(dim(settings, 0) >= diffik::kSettings, "fused: settings must have 7 entries (an 8th: lower_trust)");

    diffik::FusedArgs a;
    a.A = mat(A);
    a.b = vec(b);
    a.w = vec(w);
    a.starts = ivec(starts);
    a.tasks = imat(tasks);
    a.jac = jac.data();
    a.frames = imat(frames);
    a.site_xpos = cmat(site_xpos);
    a.site_xmat = cmat(site_xmat);
    a.xpos = cmat(xpos);
    a.xmat = cmat(xmat);
    a.geom_xpos = cmat(geom_xpos);
    a.geom_xmat = cmat(geom_xmat);
    a.frame_data = cmat(frame_data);
    a.qpos = cvec(qpos);
    a.posture_data = cmat(posture_data);
    a.cfg_dof = ivec(cfg_dof);
    a.cfg_data = cmat(cfg_data);
    a.vel_dof = ivec(vel_dof);
    a.vel_limit = cvec(vel_limit);
    a.settings = cvec(settings);
    return a;
}

// A copy of an index array (the plan's structure, checked once and kept out of reach).
struct IndexCopy {
    std::vector<i64> data;
    i64 rows = 0, cols = 1;
    template <class X>
    void assign(const X& x) {
        rows = dim(x, 0);
        cols = x.ndim() > 1 ? dim(x, 1) : 1;
        data.assign(x.data(), x.data() + rows * cols);
    }
    VecRefT<const i64> vec() const { return VecRefT<const i64>(data.data(), rows); }
    MatRefT<const i64> mat() const { return MatRefT<const i64>(data.data(), rows, cols); }
};

// The dof chains of `count` frames whose Jacobians go() computes (Kernel.set_chains,
// Kernel.set_rel_chains): frame f's dofs dofs[starts[f]:starts[f+1]] (each in [0, n)) and its
// body's root roots[f] (>= 0; max_root the largest), checked; `who` names the caller in errors.
struct DofChains {
    IndexCopy starts, dofs, roots;
    i64 max_root = -1;
    template <class I1>
    void assign(const I1& starts_, const I1& dofs_, const I1& roots_, i64 count, i64 n, const std::string& who) {
        auto say = [&who](const char* what) { return who + ": " + what; };
        starts.assign(starts_);
        dofs.assign(dofs_);
        roots.assign(roots_);
        require(starts.rows == count + 1 && roots.rows == count,
                say("starts must have one entry per frame and one more, roots one per frame").c_str());
        const i64* st = starts.data.data();
        require(st[0] == 0 && st[count] == dofs.rows, say("starts must run from 0 to len(dofs)").c_str());
        for (i64 f = 0; f < count; ++f) require(st[f] <= st[f + 1], say("starts must not decrease").c_str());
        check_dofs(dofs.vec(), n, say("a dof is out of range").c_str());
        max_root = -1;
        for (i64 f = 0; f < count; ++f) {
            require(roots.data[f] >= 0, say("a root is negative").c_str());
            max_root = std::max(max_root, roots.data[f]);
        }
    }
};

using Held1 = nb::ndarray<const double, nb::numpy, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using View1 = nb::ndarray<double, nb::numpy, nb::ndim<1>, nb::device::cpu>;  // any stride
using Act3 = nb::ndarray<i8, nb::numpy, nb::ndim<3>, nb::c_contig, nb::device::cpu>;

bool is_little_endian() {
    const std::uint16_t one = 1;
    unsigned char first;
    std::memcpy(&first, &one, 1);
    return first == 1;
}
using Held2 = nb::ndarray<const double, nb::numpy, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using Held3 = nb::ndarray<const double, nb::numpy, nb::ndim<3>, nb::c_contig, nb::device::cpu>;

// A step's result as Python receives it: (code, dq, v, info (9, L), active (L, nv + p)).
auto result_tuple(diffik::StepResult& r, i64 L) {
    const size_t L_ = static_cast<size_t>(L), cols = static_cast<size_t>(r.active_cols);
    return std::make_tuple(r.code, to_numpy(std::move(r.d)), to_numpy(std::move(r.v)),
                           to_numpy(std::move(r.info), {9, L_}),
                           to_numpy(std::move(r.active), {L_, cols}));
}

// The kernel as Python calls it (qpik.diffik.compiled.Kernel):
//
// Kernel(A, b, w, starts, tasks, jac, frames, frame_data, posture_data, posture_map,
//        cfg_dof, cfg_qadr, cfg_data, vel_dof, vel_limit, settings, com_jac, com_body,
//        com_data, rel_jac, rel_frames, rel_data, nq, user_mu=None, lin_starts=None,
//        lin_const=None, lin_data=None, ke_data=None, eq_map=None, eq_data=None)
//   One stack's compiled step (built by make_plan). The index arrays are copied and checked
//   once; the float arrays are held by reference (float64 C-contiguous, never copied: the
//   plan writes into them before each call). ``A, b, w`` (M, nv), (M,), (M,) are filled
//   (level ``k`` in rows ``starts[k]:starts[k+1]``). ``tasks`` (T, 4) rows: kind (0 frame,
//   1 posture, 2 CoM, 3 relative frame, 4 damping, 5 rows supplied by the task), index into
//   that kind's arrays, level, first row. A kind-5 task's rows of ``A, b, w`` are written by
//   the caller before each call and left as they are; ``user_mu[u]`` (U,) is its LM term,
//   added to its level's regularisation in the stack's order (optional: None, no such
//   task). Kind 6, a linear task (qpik's CouplingTask of linear couplings, tasks/linear.hpp):
//   task ``i`` owns the stacked rows ``r0:r1 = lin_starts[i]:lin_starts[i+1]`` of
//   ``lin_const`` (K, nv + nq + 1), each its constant Jacobian row, its coefficients over
//   qpos and its offset (held, written once), and the columns ``r0:r1`` of ``lin_data``
//   (3, K): its rows' costs, then its gain and LM damping in column ``r0`` (written before
//   each call); the three are optional, together. Kind 13, a kinetic-energy task
//   (tasks/kinetic.hpp): row ``i`` of ``ke_data`` (E, 2) its cost and 1 / dt^2 (written
//   before each call); its M(q) made by the kernel (set_inertia, attach_inertia). Kind 15,
//   an equality-constraint task (tasks/equality.hpp): row ``i`` of ``eq_map`` (Q, neq + 1)
//   its planned rows, then its position of each equality (-1: not its), of ``eq_data`` (Q,
//   neq + 2) its costs by position, gain and LM damping; its rows MuJoCo's, attach_efc.
//   Frame ``f``: ``jac[f]`` its world-aligned Jacobian (6, nv); ``frames[f]`` (kind
//   0/1/2 site/body/geom, id) picks its pose; ``frame_data[f]`` = target
//   ``wxyz_xyz`` (7), cost (6), gain, lm_damping. Posture ``p``: ``posture_data[p]`` =
//   target (nq), cost (nv), gain, lm_damping; ``posture_map`` (nv, 2): per dof, kind (0
//   hinge/slide, 1 free joint, 2 first dof of a ball joint, 3 its others) and qpos address.
//   Position limits: ``cfg_dof``, ``cfg_qadr`` (each dof's qpos address) and ``cfg_data``
//   rows (lower, upper, gain); velocity limits ``vel_dof``, ``vel_limit`` [per s].
//   ``settings``: see ``DT, DAMPING, ...``. CoM ``c``: ``com_jac[c]`` (3, nv) from
//   mj_jacSubtreeCom, ``com_body[c]`` its subtree's body, ``com_data[c]`` = target [m,
//   world] (3), cost (3), gain, lm_damping. Relative frame ``r``: ``rel_jac[r]`` (12, nv)
//   the frame's then the root's world-aligned Jacobians, ``rel_frames[r]`` = frame kind,
//   id, root kind, id, ``rel_data[r]`` as ``frame_data`` with the target in the root frame.
// Kernel.step(qpos, site_xpos, site_xmat, xpos, xmat, geom_xpos, geom_xmat, subtree_com,
//             G, h, warm, canonical, max_iter) -> (code, dq, v, info, active)
//   Rows of every task, the limits' box, general rows ``G dq <= h`` (p, nv) held at every
//   level, and the cascade, in one call. ``warm`` (L, nv + p) int8: the active sets to try
//   first; ``canonical``: warm starting on. ``code`` OK or why the QP path must answer;
//   ``info`` (9, L) rows: residual, sigma, lambda^2, status, iterations, then the
//   certificate (primal, stationarity, dual, complementarity); ``active`` (L, nv + p) int8.
// Kernel.attach(owner, <step's first 8 arguments>); Kernel.run(G, h, warm, canonical, max_iter)
//   MuJoCo's arrays of one MjData (owner), checked and held once (its arrays never move;
//   the owner is kept alive with them); run is step on them, without passing them again.
// Kernel.set_slots(views, scalar); Kernel.attach_out(d, v, info, active, qpos, defer);
// Kernel.set_chains(jac, starts, dofs, roots); Kernel.attach_chains(cdof, subtree_com);
// Kernel.set_sources(sources); Kernel.go(dt, damping, row, warm, canonical, max_iter) -> code
//   The lean step (qpik.diffik.compiled.CompiledPlan._lean), without general rows: the
//   tasks' values (read from their objects, each into its slot: a view of the plan's
//   arrays) written by the kernel,
//   the frames' Jacobians computed as MuJoCo's mj_jac does (when chains are set), and the
//   answers written into row `row` of the attached outputs (no array allocated per call).
//   code -1: a value is not what its slot takes as it is (nothing solved; the caller writes
//   the values its general way and calls run).
// Kernel.go_cold(dt, damping, row, max_iter) -> code
//   go(dt, damping, row, None, False, max_iter) with positional arguments only (nanobind's
//   simple dispatch: the per-step call of qpik.IKSolver.step's plain lane).
// Kernel.attach_aux(owner, <step's first 8 arguments>); Kernel.correct(row, shift, max_iter)
//   -> code
//   A second-order correction pass (qpik.StepOptions.correction_passes) of the step the last
//   go() wrote into row `row`: the held levels (solved, residual met; decided on the first
//   pass) get their targets shifted by the remainder e(q (+) dq) - e(q) - J dq, the errors
//   at q (+) dq read from the aux MjData's arrays (the caller's kinematics there), and the
//   cascade is solved again on the same rows and box; the answers overwrite the row.
// Kernel.rows(<step's first 10 arguments>) -> (code, reg, lb, ub)
//   The hierarchy's rows and limits without solving it: fills ``A, b, w``; ``code`` OK,
//   NOT_FINITE (a row or regularisation) or CONFLICT (velocity-like limits of a dof).
// boxes(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, vel_dof, vel_limit, n)
//       -> (lb, ub, i)
//   The limits' box as the kernel computes it: position bounds ``gain (upper - q)``,
//   ``-gain (q - lower)`` (recoverable), velocity bounds ``|dq| <= v_max dt`` (hard),
//   merged by :func:`qpik.core.kernels.merge_boxes`.
//
// The one-call step of one stack (qpik.diffik.compiled.CompiledPlan builds it once): the plan's
// structure (index arrays, copied and checked here) and its float arrays (held by
// reference: the plan writes the tasks' targets, costs and MuJoCo's Jacobians into them
// before each call). A call passes only MuJoCo's state; its shapes are checked per call.
class Kernel {
    struct Slot;  // defined below

  public:
    Kernel(Out2 A, Out1 b, Out1 w, const I1& starts, const I2& tasks, Held3 jac, const I2& frames,
           Held2 frame_data, Held2 posture_data, const I2& posture_map, const I1& cfg_dof,
           const I1& cfg_qadr, Held2 cfg_data, const I1& vel_dof, Held1 vel_limit, Held1 settings,
           Held3 com_jac, const I1& com_body, Held2 com_data, Held3 rel_jac, const I2& rel_frames,
           Held2 rel_data, i64 nq, std::optional<Held1> user_mu, std::optional<I1> lin_starts,
           std::optional<Held2> lin_const, std::optional<Held2> lin_data,
           std::optional<Held2> ke_data, std::optional<I2> eq_map, std::optional<Held2> eq_data)
        : A_(A), b_(b), w_(w), jac_(jac), frame_data_(frame_data), posture_data_(posture_data),
          cfg_data_(cfg_data), vel_limit_(vel_limit), settings_(settings), com_jac_(com_jac),
          com_data_(com_data), rel_jac_(rel_jac), rel_data_(rel_data), user_mu_(std::move(user_mu)),
          lin_const_(std::move(lin_const)), lin_data_(std::move(lin_data)), ke_data_(std::move(ke_data)),
          eq_data_(std::move(eq_data)), nq_(nq) {
        const i64 n = dim(A, 1), M = dim(A, 0);
        n_ = n;
        require(nq >= n, "Kernel: nq must be >= nv");
        require(dim(b, 0) == M && dim(w, 0) == M, "Kernel: b and w must have shape (M,)");
        starts_.assign(starts);
        const i64 L = starts_.rows - 1;
        require(L >= 0, "Kernel: starts must have L + 1 >= 1 entries");
        const i64* s = starts_.data.data();
        require(s[0] == 0 && s[L] == M, "Kernel: starts must run from 0 to M");
        for (i64 k = 0; k < L; ++k) require(s[k] <= s[k + 1], "Kernel: starts must not decrease");
        L_ = L;
        frames_.assign(frames);
        rel_frames_.assign(rel_frames);
        const i64 F = frames_.rows, R = rel_frames_.rows, C = dim(com_body, 0);
        const i64 P = dim(posture_data, 0);
        require(dim(frames, 1) == 2, "Kernel: frames must have shape (F, 2)");
        require(dim(rel_frames, 1) == 4, "Kernel: rel_frames must have shape (R, 4)");
        require(dim(jac, 0) == F && dim(jac, 1) == 6 && dim(jac, 2) == n,
                "Kernel: jac must have shape (F, 6, nv)");
        require(dim(frame_data, 0) == F &&
                    (dim(frame_data, 1) == diffik::kFrameData || dim(frame_data, 1) == diffik::kPoseData),
                "Kernel: frame_data must have shape (F, 15), or (F, 20) with pose tasks");
        require(dim(posture_data, 1) == nq + n + 2, "Kernel: posture_data must have shape (P, nq + nv + 2)");
        require(dim(com_jac, 0) == C && dim(com_jac, 1) == 3 && dim(com_jac, 2) == n,
                "Kernel: com_jac must have shape (C, 3, nv)");
        require(dim(com_data, 0) == C && dim(com_data, 1) == diffik::kComData,
                "Kernel: com_data must have shape (C, 8)");
        require(dim(rel_jac, 0) == R && dim(rel_jac, 1) == 12 && dim(rel_jac, 2) == n,
                "Kernel: rel_jac must have shape (R, 12, nv)");
        require(dim(rel_data, 0) == R && dim(rel_data, 1) == diffik::kFrameData,
                "Kernel: rel_data must have shape (R, 15)");
        for (i64 k = 0; k < 3; ++k) max_id_[k] = -1;
        auto note = [&](i64 kind, i64 fid) {
            require(kind >= 0 && kind <= 2, "Kernel: a frame kind is not 0 (site), 1 (body) or 2 (geom)");
            require(fid >= 0, "Kernel: a frame id is negative");
            max_id_[kind] = std::max(max_id_[kind], fid);
        };
        for (i64 f = 0; f < F; ++f) note(frames_.mat()(f, 0), frames_.mat()(f, 1));
        for (i64 r = 0; r < R; ++r) {
            note(rel_frames_.mat()(r, 0), rel_frames_.mat()(r, 1));
            note(rel_frames_.mat()(r, 2), rel_frames_.mat()(r, 3));
        }
        com_body_.assign(com_body);
        max_body_ = -1;
        for (i64 c = 0; c < C; ++c) {
            require(com_body_.data[c] >= 0, "Kernel: a CoM body id is negative");
            max_body_ = std::max(max_body_, com_body_.data[c]);
        }
        // Linear tasks: lin_starts (U + 1) from 0 to K, lin_const (K, nv + nq + 1), lin_data (3, K).
        require(lin_starts.has_value() == lin_const_.has_value() &&
                    lin_starts.has_value() == lin_data_.has_value(),
                "Kernel: lin_starts, lin_const and lin_data come together");
        i64 lin_tasks = 0;
        if (lin_starts) {
            lin_starts_.assign(*lin_starts);
            lin_tasks = lin_starts_.rows - 1;
            require(lin_tasks >= 0, "Kernel: lin_starts must have U + 1 >= 1 entries");
            const i64* ls = lin_starts_.data.data();
            require(ls[0] == 0, "Kernel: lin_starts must start at 0");
            for (i64 u = 0; u < lin_tasks; ++u) require(ls[u] <= ls[u + 1], "Kernel: lin_starts must not decrease");
            const i64 K = ls[lin_tasks];
            require(dim(*lin_const_, 0) == K && dim(*lin_const_, 1) == n + nq + 1,
                    "Kernel: lin_const must have shape (K, nv + nq + 1), K = lin_starts[-1]");
            require(dim(*lin_data_, 0) == 3 && dim(*lin_data_, 1) == K,
                    "Kernel: lin_data must have shape (3, K), K = lin_starts[-1]");
        }
        // Kinetic-energy tasks: ke_data (E, 2); M(q) not made yet (NaN: their rows decline)
        const i64 E = ke_data_ ? dim(*ke_data_, 0) : 0;
        if (ke_data_) require(dim(*ke_data_, 1) == 2, "Kernel: ke_data must have shape (E, 2)");
        if (E > 0) inertia_.assign(static_cast<size_t>(n * n), std::numeric_limits<double>::quiet_NaN());
        // Equality-constraint tasks: eq_map (Q, neq + 1) planned rows >= 0 and positions >= -1,
        // eq_data (Q, neq + 2)
        require(eq_map.has_value() == eq_data_.has_value(), "Kernel: eq_map and eq_data come together");
        i64 Q = 0;
        if (eq_map) {
            eq_map_.assign(*eq_map);
            Q = eq_map_.rows;
            require(dim(*eq_data_, 0) == Q && dim(*eq_data_, 1) == eq_map_.cols + 1 && eq_map_.cols >= 1,
                    "Kernel: eq_map must have shape (Q, neq + 1), eq_data (Q, neq + 2)");
            for (i64 q = 0; q < Q; ++q) {
                require(eq_map_.mat()(q, 0) >= 0, "Kernel: an equality task's planned rows are negative");
                for (i64 e = 1; e < eq_map_.cols; ++e) {
                    const i64 p = eq_map_.mat()(q, e);
                    require(p >= -1 && p < eq_map_.cols - 1, "Kernel: an equality position is out of range");
                }
            }
        }
        tasks_.assign(tasks);
        require(dim(tasks, 1) == 4, "Kernel: tasks must have shape (T, 4)");
        for (i64 k = 0; k < tasks_.rows; ++k) {
            const i64 kind = tasks_.mat()(k, 0), index = tasks_.mat()(k, 1);
            const i64 level = tasks_.mat()(k, 2), row = tasks_.mat()(k, 3);
            i64 count = 0, size = 0;
            const i64 U = user_mu_ ? dim(*user_mu_, 0) : 0;
            switch (kind) {
                case diffik::FRAME: case diffik::FRAME | diffik::UNIT_ROWS: count = F; size = 6; break;
                case diffik::POSTURE: case diffik::DAMPING_TASK: count = P; size = n; break;
                case diffik::COM: count = C; size = 3; break;
                case diffik::RELATIVE: count = R; size = 6; break;
                case diffik::ROWS: count = U; size = 0; break;  // its rows: the caller's
                case diffik::LINEAR: case diffik::LINEAR | diffik::UNIT_ROWS: count = lin_tasks; break;
                case diffik::JOINT_LIMITS: count = lin_tasks; break;  // (lin_const checked above)
                case diffik::POSE_POSITION: case diffik::POSE_ORIENTATION: case diffik::POSE_FULL:
                    require(dim(frame_data, 1) == diffik::kPoseData,
                            "Kernel: frame_data must have shape (F, 20) with pose tasks");
                    count = F;
                    size = tasks::pose_part_rows(kind - diffik::POSE_BASE);
                    break;
                case diffik::KINETIC: count = E; size = n; break;
                case diffik::LOOK_AT: case diffik::AXIS_ALIGN:
                    require(dim(frame_data, 1) == diffik::kPoseData,
                            "Kernel: frame_data must have shape (F, 20) with look-at or axis-align tasks");
                    count = F;
                    size = 3;
                    break;
                case diffik::EQUALITY: count = Q; break;  // (its size: eq_map's, below)
                case diffik::MANIPULABILITY:
                    require(dim(frame_data, 1) == diffik::kPoseData,
                            "Kernel: frame_data must have shape (F, 20) with manipulability tasks");
                    count = F;
                    size = 1;
                    break;
                default: require(false, "Kernel: a task kind is not 0 to 15, 32 or 38 (a constraint's)");
            }
            require(index >= 0 && index < count, "Kernel: a task index is out of range");
            if ((kind & ~diffik::UNIT_ROWS) == diffik::LINEAR || kind == diffik::JOINT_LIMITS)
                size = lin_starts_.data[index + 1] - lin_starts_.data[index];
            if (kind == diffik::JOINT_LIMITS) require(size == 1, "Kernel: a joint-limit task has one row");
            if (kind == diffik::EQUALITY) size = eq_map_.mat()(index, 0);
            require(level >= 0 && level < L, "Kernel: a task level is out of range");
            require(row >= 0 && row + size <= M, "Kernel: a task's rows are out of range of A");
        }
        posture_map_.assign(posture_map);
        require(dim(posture_map, 0) == n && dim(posture_map, 1) == 2,
                "Kernel: posture_map must have shape (nv, 2)");
        for (i64 i = 0; i < n; ++i) {
            const i64 kind = posture_map_.mat()(i, 0), adr = posture_map_.mat()(i, 1);
            require(kind >= 0 && kind <= 3, "Kernel: a posture_map kind is not 0 to 3");
            const i64 width = kind == diffik::BALL_FIRST ? 4 : 1;
            require(adr >= 0 && adr + width <= nq, "Kernel: a posture_map address is out of range");
            if (kind == diffik::BALL_FIRST)
                require(i + 2 < n && posture_map_.mat()(i + 1, 0) == diffik::BALL_OTHER &&
                            posture_map_.mat()(i + 2, 0) == diffik::BALL_OTHER,
                        "Kernel: a ball joint needs three dofs in posture_map");
        }
        cfg_dof_.assign(cfg_dof);
        cfg_qadr_.assign(cfg_qadr);
        require(dim(cfg_qadr, 0) == cfg_dof_.rows && dim(cfg_data, 0) == cfg_dof_.rows &&
                    dim(cfg_data, 1) == 3,
                "Kernel: cfg_qadr and cfg_data must have len(cfg_dof) rows (cfg_data 3 columns)");
        check_dofs(cfg_dof_.vec(), n, "Kernel: a cfg_dof entry is out of range");
        check_dofs(cfg_qadr_.vec(), nq, "Kernel: a cfg_qadr entry is out of range");
        vel_dof_.assign(vel_dof);
        require(dim(vel_limit, 0) == vel_dof_.rows, "Kernel: vel_limit must have len(vel_dof) entries");
        check_dofs(vel_dof_.vec(), n, "Kernel: a vel_dof entry is out of range");
        require(dim(settings, 0) >= diffik::kSettings, "Kernel: settings must have 7 entries (an 8th: lower_trust)");
    }

    // The arguments of one call, after checking MuJoCo's arrays against the plan.
    diffik::FusedArgs args(const In1& qpos, const In2& sx, const In2& sm, const In2& x, const In2& xm,
                           const In2& gx, const In2& gm, const In2& subtree_com, const In2& G,
                           const In1& h) {
        check_poses(qpos, sx, sm, x, xm, gx, gm, subtree_com);
        return fill(qpos, sx, sm, x, xm, gx, gm, subtree_com, G, h);
    }

    // MuJoCo's arrays checked against the plan (shapes, frame ids, CoM bodies).
    void check_poses(const In1& qpos, const In2& sx, const In2& sm, const In2& x, const In2& xm,
                     const In2& gx, const In2& gm, const In2& subtree_com) const {
        require(dim(qpos, 0) == nq_, "Kernel: qpos must have shape (nq,)");
        require(dim(sx, 1) == 3 && dim(x, 1) == 3 && dim(gx, 1) == 3 && dim(subtree_com, 1) == 3,
                "Kernel: the positions must have shape (*, 3)");
        require(dim(sm, 1) == 9 && dim(xm, 1) == 9 && dim(gm, 1) == 9,
                "Kernel: the rotations must have shape (*, 9)");
        const i64 count[3] = {std::min(dim(sx, 0), dim(sm, 0)), std::min(dim(x, 0), dim(xm, 0)),
                              std::min(dim(gx, 0), dim(gm, 0))};
        for (i64 k = 0; k < 3; ++k) require(max_id_[k] < count[k], "Kernel: a frame id is out of range of its poses");
        require(max_body_ < dim(subtree_com, 0), "Kernel: a CoM body is out of range of subtree_com");
    }

    // The arguments of one call (MuJoCo's arrays already checked).
    diffik::FusedArgs fill(const In1& qpos, const In2& sx, const In2& sm, const In2& x, const In2& xm,
                           const In2& gx, const In2& gm, const In2& subtree_com, const In2& G,
                           const In1& h) {
        require(dim(G, 1) == n_ && dim(h, 0) == dim(G, 0), "Kernel: G must have shape (p, nv), h (p,)");
        last_row_ = -1;  // a call other than go(): correct() has no step to correct
        diffik::FusedArgs a = fill_poses(qpos, sx, sm, x, xm, gx, gm, subtree_com);
        a.G = CMatRef(G.data(), dim(G, 0), n_);
        a.h = cvec(h);
        return a;
    }

    // The arguments of one call without general rows (G, h empty).
    diffik::FusedArgs fill_poses(const In1& qpos, const In2& sx, const In2& sm, const In2& x,
                                 const In2& xm, const In2& gx, const In2& gm,
                                 const In2& subtree_com) {
        diffik::FusedArgs a;
        a.A = mat(A_);
        a.b = vec(b_);
        a.w = vec(w_);
        a.starts = starts_.vec();
        a.tasks = tasks_.mat();
        a.jac = jac_.data();
        a.frames = frames_.mat();
        a.site_xpos = cmat(sx);
        a.site_xmat = cmat(sm);
        a.xpos = cmat(x);
        a.xmat = cmat(xm);
        a.geom_xpos = cmat(gx);
        a.geom_xmat = cmat(gm);
        a.frame_data = cmat(frame_data_);
        a.qpos = cvec(qpos);
        a.posture_data = cmat(posture_data_);
        a.cfg_dof = cfg_dof_.vec();
        a.cfg_data = cmat(cfg_data_);
        a.vel_dof = vel_dof_.vec();
        a.vel_limit = cvec(vel_limit_);
        a.settings = cvec(settings_);
        a.posture_map = posture_map_.mat();
        a.cfg_qadr = cfg_qadr_.vec();
        a.com_jac = com_jac_.data();
        a.com_body = com_body_.vec();
        a.subtree_com = cmat(subtree_com);
        a.com_data = cmat(com_data_);
        a.rel_jac = rel_jac_.data();
        a.rel_frames = rel_frames_.mat();
        a.rel_data = cmat(rel_data_);
        a.G = CMatRef(nullptr, 0, n_);
        if (user_mu_) a.user_mu = cvec(*user_mu_);
        if (lin_const_) {
            a.lin_starts = lin_starts_.vec();
            a.lin_const = cmat(*lin_const_);
            a.lin_data = cmat(*lin_data_);
        }
        if (frame_chains_.starts.rows > 0) {
            a.chain_starts = frame_chains_.starts.vec();
            a.chain_dofs = frame_chains_.dofs.vec();
        }
        if (!dof_threshold_.empty()) a.dof_threshold = dof_threshold_.data();
        if (eq_data_) {
            a.eq_map = eq_map_.mat();
            a.eq_data = cmat(*eq_data_);
            a.efc = efc_.has_value() ? &efc_rows_ : nullptr;
        }
        if (ke_data_) {
            a.ke_data = cmat(*ke_data_);
            a.inertia = inertia_.empty() ? nullptr : inertia_.data();
        }
        return a;
    }

    // MuJoCo's arrays of one MjData held for run() (checked once; `owner`, the MjData, is kept
    // alive with them: its arrays never move).
    void attach(nb::object owner, const In1& qpos, const In2& sx, const In2& sm, const In2& x,
                const In2& xm, const In2& gx, const In2& gm, const In2& subtree_com) {
        check_poses(qpos, sx, sm, x, xm, gx, gm, subtree_com);
        attached_ = Attached{std::move(owner), qpos, sx, sm, x, xm, gx, gm, subtree_com};
        // go()'s arguments: views of arrays that never move (the plan's, held, and the
        // attached MjData's), built once here
        go_args_ = fill_poses(qpos, sx, sm, x, xm, gx, gm, subtree_com);
    }

    // The arguments of one call on the attached MjData's arrays.
    diffik::FusedArgs attached_args(const In2& G, const In1& h) {
        require(attached_.has_value(), "Kernel.run: no MjData attached (Kernel.attach)");
        const Attached& t = *attached_;
        return fill(t.qpos, t.sx, t.sm, t.x, t.xm, t.gx, t.gm, t.subtree_com, G, h);
    }

    // The slots that go()'s values are written into: writable float64 vectors of the plan's
    // arrays (views, held), each taking a vector of its length or, `scalar`, one number for
    // every entry.
    void set_slots(nb::list views, nb::list scalar) {
        require(views.size() == scalar.size(), "Kernel.set_slots: views and scalar differ in length");
        std::vector<Slot> slots;
        for (size_t i = 0; i < views.size(); ++i) {
            Slot t;
            t.view = nb::cast<View1>(views[i]);
            t.p = t.view.data();
            t.size = dim(t.view, 0);
            t.stride = t.view.stride(0);
            t.scalar = nb::cast<bool>(scalar[i]);
            slots.push_back(std::move(t));
        }
        slots_ = std::move(slots);
    }

    // One value into its slot; false when it is not what the slot takes as it is: a real
    // number (float or int) for a scalar slot, else a float64 vector of the slot's length (the
    // caller then writes the values its general way, with NumPy's conversions and errors).
    static bool load_one(const Slot& t, PyObject* o) {
        if (t.scalar) {
            double x;
            if (PyFloat_Check(o)) {
                x = PyFloat_AS_DOUBLE(o);
            } else if (PyLong_CheckExact(o)) {
                x = PyLong_AsDouble(o);
                if (x == -1.0 && PyErr_Occurred()) {
                    PyErr_Clear();
                    return false;
                }
            } else {
                return false;
            }
            for (i64 k = 0; k < t.size; ++k) t.p[k * t.stride] = x;
            return true;
        }
        FastArray fa;
        if (fast_array(o, 'd', false, fa)) {  // an ndarray read directly: the same bytes
            if (fa.ndim != 1 || fa.shape[0] != t.size) return false;
            if (t.stride == 1 && fa.strides[0] == static_cast<Py_ssize_t>(sizeof(double))) {
                std::memcpy(t.p, fa.data, sizeof(double) * static_cast<size_t>(t.size));  // both contiguous
                return true;
            }
            for (i64 k = 0; k < t.size; ++k)
                std::memcpy(t.p + k * t.stride, fa.data + k * fa.strides[0], sizeof(double));
            return true;
        }
        Py_buffer b;
        if (PyObject_GetBuffer(o, &b, PyBUF_STRIDES | PyBUF_FORMAT) != 0) {
            PyErr_Clear();
            return false;
        }
        const char* f = b.format;
        const bool ok = b.ndim == 1 && b.itemsize == 8 && b.shape[0] == t.size && f != nullptr &&
                        (f[0] == 'd' || ((f[0] == '<' || f[0] == '=' || f[0] == '@') && f[1] == 'd' &&
                                         is_little_endian())) &&
                        f[f[0] == 'd' ? 1 : 2] == '\0';
        if (ok) {
            const char* src = static_cast<const char*>(b.buf);
            for (i64 k = 0; k < t.size; ++k)
                std::memcpy(t.p + k * t.stride, src + k * b.strides[0], sizeof(double));
        }
        PyBuffer_Release(&b);
        return ok;
    }

    // Entries `pick` of a float64 vector value into slot t (its entry k = o[pick[k]]); false
    // where o is not an ndarray of float64 of one dimension holding every picked index (the
    // caller's general way then writes it, or reports it).
    static bool load_picked(const Slot& t, PyObject* o, const std::vector<i64>& pick) {
        FastArray fa;
        if (!fast_array(o, 'd', false, fa) || fa.ndim != 1) return false;
        const i64 size = static_cast<i64>(fa.shape[0]);
        for (size_t k = 0; k < pick.size(); ++k) {
            if (pick[k] >= size) return false;
            std::memcpy(t.p + static_cast<i64>(k) * t.stride, fa.data + pick[k] * fa.strides[0], sizeof(double));
        }
        return true;
    }

    // Where go() reads each slot's value but the first two (dt, damping): per slot
    // after those, (object, name) or (object, name, inner name): getattr(object, name), or
    // getattr(getattr(object, name), inner name) (a task's target pose: its wxyz_xyz).
    void set_sources(nb::list sources) {
        require(sources.size() + 2 == slots_.size(), "Kernel.set_sources: one source per slot after the first two");
        std::vector<Source> out;
        for (size_t i = 0; i < sources.size(); ++i) {
            nb::handle item = sources[i];
            require(PyTuple_Check(item.ptr()) && (PyTuple_GET_SIZE(item.ptr()) == 2 || PyTuple_GET_SIZE(item.ptr()) == 3),
                    "Kernel.set_sources: a source is (object, name) or (object, name, inner name)");
            Source src;
            src.obj = nb::borrow(PyTuple_GET_ITEM(item.ptr(), 0));
            src.name = nb::borrow(PyTuple_GET_ITEM(item.ptr(), 1));
            require(PyUnicode_Check(src.name.ptr()), "Kernel.set_sources: a name is not a str");
            src.gain = PyUnicode_CompareWithASCIIString(src.name.ptr(), "gain") == 0;
            if (PyTuple_GET_SIZE(item.ptr()) == 3) {
                nb::handle third = PyTuple_GET_ITEM(item.ptr(), 2);
                if (PyUnicode_Check(third.ptr())) {
                    src.inner = nb::borrow(third);
                } else {  // entries picked from a float64 vector: getattr(object, name)[pick]
                    require(PyList_Check(third.ptr()),
                            "Kernel.set_sources: a third item is an inner name (str) or a list of indices");
                    const Py_ssize_t m = PyList_GET_SIZE(third.ptr());
                    require(static_cast<i64>(m) == slots_[i + 2].size && !slots_[i + 2].scalar,
                            "Kernel.set_sources: one picked index per entry of the slot");
                    for (Py_ssize_t k = 0; k < m; ++k) {
                        const long long index = PyLong_AsLongLong(PyList_GET_ITEM(third.ptr(), k));
                        if (index == -1 && PyErr_Occurred()) {
                            PyErr_Clear();
                            require(false, "Kernel.set_sources: a picked index is not an int");
                        }
                        require(index >= 0, "Kernel.set_sources: a picked index is negative");
                        src.pick.push_back(static_cast<i64>(index));
                    }
                    require(!src.pick.empty(), "Kernel.set_sources: an empty list of picked indices");
                }
            }
            out.push_back(std::move(src));
        }
        sources_ = std::move(out);
    }

    // Sources first.. (and their slots, two further on) loaded as load_sources loads them;
    // false as there.
    bool load_range(size_t first) const {
        for (size_t i = first; i < sources_.size(); ++i) {
            const Source& src = sources_[i];
            PyObject* o = PyObject_GetAttr(src.obj.ptr(), src.name.ptr());
            if (o && src.inner.is_valid()) {
                PyObject* inner = o == Py_None ? nullptr : PyObject_GetAttr(o, src.inner.ptr());
                Py_DECREF(o);
                o = inner;
            }
            if (!o) {
                PyErr_Clear();
                return false;
            }
            const Slot& t = slots_[i + 2];
            const bool ok = src.pick.empty() ? load_one(t, o) : load_picked(t, o, src.pick);
            Py_DECREF(o);
            if (!ok) return false;
            // A target pose (inner name: its wxyz_xyz) whose quaternion is zero is no rotation:
            // the caller's general way reports it (InvalidTarget, tasks.checked).
            if (src.inner.is_valid() && t.size >= 4 && t.p[0] == 0.0 && t.p[t.stride] == 0.0 &&
                t.p[2 * t.stride] == 0.0 && t.p[3 * t.stride] == 0.0)
                return false;
            // A gain outside [0, 1] (or NaN), set after the build on a task that takes any
            // (mink's own classes): the caller's general way reports it (InvalidGain).
            if (src.gain && t.size == 1 && !(t.p[0] >= 0.0 && t.p[0] <= 1.0)) return false;
        }
        return true;
    }

    // The limits' values as loaded: a position limit's joint with no range (or a NaN bound),
    // a gain outside (0, 1], a speed below 0 (or NaN) are the caller's general way, which
    // reports them (LimitDefinitionError, InfeasibleLimits; boxes.limit_values, limit_bounds).
    bool limits_hold() const {
        const i64 E = dim(cfg_data_, 0);
        const double* c = cfg_data_.data();
        for (i64 e = 0; e < E; ++e)
            if (!(c[3 * e] <= c[3 * e + 1]) || !(c[3 * e + 2] > 0.0 && c[3 * e + 2] <= 1.0)) return false;
        const i64 V = dim(vel_limit_, 0);
        const double* v = vel_limit_.data();
        for (i64 j = 0; j < V; ++j)
            if (!(v[j] >= 0.0)) return false;
        return true;
    }

    // The gathered step's limit values (its tasks' are written by the caller): sources
    // first.. loaded into their slots and checked (limits_hold); false where one is not
    // taken as it is or fails the check (the caller then writes them its general way, which
    // raises the typed error).
    bool load_limits(i64 first) {
        if (slots_.size() != sources_.size() + 2 || first < 0 || static_cast<size_t>(first) > sources_.size())
            return false;
        return load_range(static_cast<size_t>(first)) && limits_hold();
    }

    // dt and damping into the first two slots, then each source's current value into its
    // slot (set_sources); false as load_one() (a value it does not take as it is, a None
    // target, an attribute that raised: its error cleared, the caller's general way
    // reports it).
    bool load_sources(double dt, double damping) const {
        if (slots_.size() != sources_.size() + 2 || slots_.size() < 2) return false;
        for (size_t s = 0; s < 2; ++s) {
            const Slot& t = slots_[s];
            const double x = s == 0 ? dt : damping;
            for (i64 k = 0; k < t.size; ++k) t.p[k * t.stride] = x;
        }
        if (!load_range(0) || !limits_hold()) return false;
        // The guards: each task attribute the plan was built from (a frame's name and type)
        // still that object, or equal to it; else false (the task changed beyond the plan:
        // the caller's general way, where the QP path answers).
        for (const Guard& g : guards_) {
            PyObject* o = PyObject_GetAttr(g.obj.ptr(), g.name.ptr());
            if (!o) {
                PyErr_Clear();
                return false;
            }
            int same = o == g.value.ptr() ? 1 : PyObject_RichCompareBool(o, g.value.ptr(), Py_EQ);
            Py_DECREF(o);
            if (same != 1) {
                PyErr_Clear();
                return false;
            }
        }
        return true;
    }

    // The task attributes the plan was built from, (object, name, value) each: load_sources
    // declines a step where one is no longer that value (see there).
    void set_guards(nb::list guards) {
        std::vector<Guard> out;
        for (size_t i = 0; i < guards.size(); ++i) {
            nb::handle item = guards[i];
            require(PyTuple_Check(item.ptr()) && PyTuple_GET_SIZE(item.ptr()) == 3,
                    "Kernel.set_guards: a guard is (object, name, value)");
            Guard g;
            g.obj = nb::borrow(PyTuple_GET_ITEM(item.ptr(), 0));
            g.name = nb::borrow(PyTuple_GET_ITEM(item.ptr(), 1));
            g.value = nb::borrow(PyTuple_GET_ITEM(item.ptr(), 2));
            require(PyUnicode_Check(g.name.ptr()), "Kernel.set_guards: a name is not a str");
            out.push_back(std::move(g));
        }
        guards_ = std::move(out);
    }

    // The frame Jacobians go() computes itself, as MuJoCo's mj_jacSite / mj_jacBody /
    // mj_jacGeom do (mj_jac: per dof of the frame's chain, the rotation rows cdof[0:3] and
    // the translation rows cdof[3:6] + cdof[0:3] x (point - subtree_com[root])): `jac` the
    // plan's (F, 6, nv) (the array the kernel holds), frame f's dofs
    // dofs[starts[f]:starts[f+1]], its body's root roots[f]; cdof (nv, 6) and subtree_com
    // (nbody, 3) the attached MjData's (held; attach_chains again when it changes).
    void set_chains(Out3 jac, const I1& starts, const I1& dofs, const I1& roots) {
        const i64 F = frames_.rows;
        require(jac.data() == jac_.data() && dim(jac, 0) == F && dim(jac, 1) == 6 && dim(jac, 2) == n_,
                "Kernel.set_chains: jac must be the kernel's jac");
        frame_chains_.assign(starts, dofs, roots, F, n_, "Kernel.set_chains");
        jac_w_ = jac;
        cdof_.reset();
        if (attached_) {  // (go()'s arguments view the chains: made again)
            const Attached& t = *attached_;
            go_args_ = fill_poses(t.qpos, t.sx, t.sm, t.x, t.xm, t.gx, t.gm, t.subtree_com);
        }
    }

    // go() computes the relative-frame tasks' Jacobians too (as set_chains the frames'):
    // `rel_jac` the kernel's (R, 12, nv) array, read as 2R frames of (6, nv): frame 2r the
    // task r's frame, 2r + 1 its root frame (rel_frames' two pairs), each frame k's dofs
    // dofs[starts[k]:starts[k+1]] and its body's root roots[k].
    void set_rel_chains(Out3 rel_jac, const I1& starts, const I1& dofs, const I1& roots) {
        const i64 R = rel_frames_.rows;
        require(rel_jac.data() == rel_jac_.data() && dim(rel_jac, 0) == R && dim(rel_jac, 1) == 12 &&
                    dim(rel_jac, 2) == n_,
                "Kernel.set_rel_chains: rel_jac must be the kernel's rel_jac");
        rel_chains_.assign(starts, dofs, roots, 2 * R, n_, "Kernel.set_rel_chains");
        rel_w_ = rel_jac;
        cdof_.reset();
    }

    // The CoM tasks' Jacobians computed by the kernel on each go() (model::subtree_com_jacobian,
    // from the MjData attach_chains holds): com_jac the kernel's (C, 3, nv) array, point and
    // root (C, nv) body ids and scale (C, nv) each task's per-dof chain
    // (qpik.model.com.subtree_com_chain).
    void set_com_chains(Out3 jac, const I2& point, const I2& root, const In2& scale) {
        const i64 C = com_body_.rows;
        require(jac.data() == com_jac_.data() && dim(jac, 0) == C && dim(jac, 1) == 3 && dim(jac, 2) == n_,
                "Kernel.set_com_chains: com_jac must be the kernel's com_jac");
        com_point_.assign(point);
        com_root_.assign(root);
        require(com_point_.rows == C && com_point_.cols == n_ && com_root_.rows == C && com_root_.cols == n_ &&
                    dim(scale, 0) == C && dim(scale, 1) == n_,
                "Kernel.set_com_chains: point, root and scale must have shape (C, nv)");
        com_scale_.assign(scale.data(), scale.data() + C * n_);
        max_com_body_ = -1;
        for (i64 e = 0; e < C * n_; ++e) {
            require(std::isfinite(com_scale_[e]), "Kernel.set_com_chains: a scale is not finite");
            if (com_scale_[e] == 0.0) continue;
            require(com_point_.data[e] >= 0 && com_root_.data[e] >= 0, "Kernel.set_com_chains: a body is negative");
            max_com_body_ = std::max(max_com_body_, std::max(com_point_.data[e], com_root_.data[e]));
        }
        com_w_ = jac;
        cdof_.reset();
    }

    void attach_chains(const In2& cdof, const In2& subtree_com) {
        require(jac_w_.has_value() || com_w_.has_value() || rel_w_.has_value(),
                "Kernel.attach_chains: no chains (Kernel.set_chains)");
        require(dim(cdof, 0) == n_ && dim(cdof, 1) == 6, "Kernel.attach_chains: cdof must have shape (nv, 6)");
        require(dim(subtree_com, 1) == 3 && frame_chains_.max_root < dim(subtree_com, 0) &&
                    max_com_body_ < dim(subtree_com, 0) && rel_chains_.max_root < dim(subtree_com, 0),
                "Kernel.attach_chains: subtree_com must have shape (nbody, 3), every root in range");
        cdof_ = Chains{cdof, subtree_com};
    }

    // The MjData's constraint rows (mj_makeConstraint) that the equality-constraint tasks
    // read at the next steps: efc_J (dense nefc * nv, or sparse with efc_J_rownnz, _rowadr
    // (nefc) and _colind (its length)), efc_pos, efc_type, efc_id (nefc); checked here (every
    // index in range; false, and none attached, where they do not: the tasks then decline).
    // Attach them again after each update of the MjData (their views change with nefc).
    bool attach_efc(const In1& J, const In1& pos, const Int32In1& type, const Int32In1& id, const Int32In1& rownnz,
                    const Int32In1& rowadr, const Int32In1& colind, bool sparse) {
        efc_.reset();  // (until these check: every equality-constraint task declines)
        if (attached_) go_args_.efc = nullptr;
        const tasks::EfcRows rows{dim(pos, 0), n_, sparse, J.data(), pos.data(), type.data(), id.data(),
                                  rownnz.data(), rowadr.data(), colind.data()};
        if (!tasks::efc_rows_fit(rows, dim(J, 0), dim(type, 0), dim(id, 0), dim(rownnz, 0), dim(rowadr, 0),
                                 dim(colind, 0)))
            return false;
        efc_ = Efc{J, pos, type, id, rownnz, rowadr, colind};
        efc_rows_ = rows;
        if (attached_) go_args_.efc = &efc_rows_;
        return true;
    }

    // Each dof's threshold (nv,) for the manipulability tasks whose frame a ball or free joint
    // moves (model::hessian_weights_any: t[b] in [0, nv], a dof a moves column b's axis where
    // a < t[b]).
    void set_dof_thresholds(const In<i64, 1>& threshold) {
        require(dim(threshold, 0) == n_, "Kernel.set_dof_thresholds: threshold must have shape (nv,)");
        for (i64 i = 0; i < n_; ++i)
            require(threshold.data()[i] >= 0 && threshold.data()[i] <= n_,
                    "Kernel.set_dof_thresholds: a threshold is out of [0, nv]");
        dof_threshold_.assign(threshold.data(), threshold.data() + n_);
        if (attached_) go_args_.dof_threshold = dof_threshold_.data();
    }

    // The model's tree for the kinetic-energy tasks' inertia matrix (model::inertia_matrix):
    // per body its parent, per dof its body, parent dof (-1: none), armature and fixed
    // diagonal (NaN: none).
    void set_inertia(const In<i64, 1>& body_parent, const In<i64, 1>& dof_body, const In<i64, 1>& dof_parent,
                     const In1& armature, const In1& fixed) {
        tree_ = bind::OwnedTree(body_parent, dof_body, dof_parent, armature, fixed,
                                "Kernel.set_inertia: body_parent (nbody,), dof_body, dof_parent and armature "
                                "(nv,) must describe a MuJoCo model's tree");
        require(static_cast<i64>(tree_.dof_body.size()) == n_, "Kernel.set_inertia: the tree must have nv dofs");
        crb_.assign(10 * tree_.body_parent.size(), 0.0);
        inertia_in_.reset();
    }

    // The MjData whose cdof (nv, 6) and cinert (nbody, 10) (mj_comPos) make M(q) at each
    // step (held; attach again when the MjData changes).
    void attach_inertia(const In2& cdof, const In2& cinert) {
        require(!tree_.dof_body.empty() || n_ == 0, "Kernel.attach_inertia: no tree (Kernel.set_inertia)");
        require(dim(cdof, 0) == n_ && dim(cdof, 1) == 6 &&
                    dim(cinert, 0) == static_cast<i64>(tree_.body_parent.size()) && dim(cinert, 1) == 10,
                "Kernel.attach_inertia: cdof must have shape (nv, 6), cinert (nbody, 10)");
        inertia_in_ = Chains{cdof, cinert};
    }

    // The Jacobians of every chain set (set_chains, set_rel_chains, set_com_chains) into their
    // arrays, from the attached cdof and subtree_com (attach_chains): go()'s, and the gathered
    // step's (run), bitwise MuJoCo's; and M(q) where kinetic-energy tasks need it.
    void make_jacobians() {
        if (inertia_in_ && !inertia_.empty())
            model::inertia_matrix(tree_.view(), inertia_in_->subtree_com.data(), inertia_in_->cdof.data(),
                                  crb_.data(), inertia_.data());
        if (!(jac_w_ || com_w_ || rel_w_)) return;
        require(cdof_.has_value(), "Kernel.make_jacobians: no cdof attached (Kernel.attach_chains)");
        require(attached_.has_value(), "Kernel.make_jacobians: no MjData attached (Kernel.attach)");
        if (jac_w_) frame_jacobians();
        if (com_w_) com_jacobians();
        if (rel_w_) rel_jacobians();
    }

    // The CoM tasks' Jacobians into com_jac (see set_com_chains).
    void com_jacobians() {
        const auto& c = *cdof_;
        const i64 C = com_point_.rows, n = n_;
        for (i64 k = 0; k < C; ++k)
            model::subtree_com_jacobian(c.cdof.data(), c.subtree_com.data(), n, com_point_.data.data() + k * n,
                                        com_root_.data.data() + k * n, com_scale_.data() + k * n,
                                        com_w_->data() + k * 3 * n);
    }

    // The frames' Jacobians into jac (see set_chains).
    void frame_jacobians() {
        const auto frame = [this](i64 f, i64& kind, i64& fid) {
            kind = frames_.mat()(f, 0);
            fid = frames_.mat()(f, 1);
        };
        chain_jacobians(frames_.rows, frame, jac_w_->data(), frame_chains_);
    }

    // The relative-frame tasks' Jacobians into rel_jac (see set_rel_chains).
    void rel_jacobians() {
        const auto frame = [this](i64 k, i64& kind, i64& fid) {
            kind = rel_frames_.mat()(k / 2, 2 * (k % 2));
            fid = rel_frames_.mat()(k / 2, 2 * (k % 2) + 1);
        };
        chain_jacobians(2 * rel_frames_.rows, frame, rel_w_->data(), rel_chains_);
    }

    // count frames' Jacobians (6, nv) into J, as mj_jac computes them: frame f (kind and id
    // from frame(f, kind, id)) by its dof chain dofs[st[f]:st[f+1]] and its body's root roots[f].
    template <class Frame>
    void chain_jacobians(i64 count, const Frame& frame, double* J, const DofChains& chains) {
        const auto& t = *attached_;
        const auto& c = *cdof_;
        const double* cdof = c.cdof.data();
        const double* com = c.subtree_com.data();
        const i64* st = chains.starts.data.data();
        const i64* dofs = chains.dofs.data.data();
        const i64 n = n_;
        for (i64 f = 0; f < count; ++f) {
            double* jp = J + f * 6 * n;
            double* jr = jp + 3 * n;
            std::fill(jp, jp + 6 * n, 0.0);
            i64 kind = 0, fid = 0;
            frame(f, kind, fid);
            const auto& pos = kind == 0 ? t.sx : (kind == 1 ? t.x : t.gx);
            model::chain_point_jacobian(cdof, n, dofs + st[f], st[f + 1] - st[f], pos.data() + 3 * fid,
                                        com + 3 * chains.roots.data[f], jp, jr);
        }
    }

    // The rows that go() writes its answers into (K steps each; held): dq, v (K, nv), info
    // (K, 9, L), active sets (K, L, nv) int8, qpos (K, nq).
    // defer (K, defer_width()): per step, the cascade's records of the levels whose sigma it
    // deferred (core::CascadeResult::deferred: L header entries, -1 where none, then the
    // records; info's sigma NaN there), for core::deferred_sigma (qpik.core.kernels.resolve_sigma).
    void attach_out(Out2 d, Out2 v, Out3 info, Act3 active, Out2 qpos, Out2 defer) {
        const i64 K = dim(d, 0);
        require(dim(d, 1) == n_ && dim(v, 0) == K && dim(v, 1) == n_,
                "Kernel.attach_out: d and v must have shape (K, nv)");
        require(dim(info, 0) == K && dim(info, 1) == 9 && dim(info, 2) == L_,
                "Kernel.attach_out: info must have shape (K, 9, L)");
        require(dim(active, 0) == K && dim(active, 1) == L_ && dim(active, 2) == n_,
                "Kernel.attach_out: active must have shape (K, L, nv)");
        require(dim(qpos, 0) == K && dim(qpos, 1) == nq_, "Kernel.attach_out: qpos must have shape (K, nq)");
        require(dim(defer, 0) == K && dim(defer, 1) == defer_width(),
                "Kernel.attach_out: defer must have shape (K, defer_width)");
        out_ = Outputs{d, v, info, active, qpos, defer, K};
    }

    // One step on the attached MjData without general rows: values into the slots, the
    // cascade, its answers into row `row` of the attached outputs. Returns -1 when the values
    // do not load (nothing solved), else the step's code (its answers written only when OK).
    // The lean step: dt and damping and the sources' values (set_sources) read into the slots
    // by the kernel itself, then solve_into.
    // warm: None, or an int8 (L, nv) array: a C-contiguous int8 numpy.ndarray read directly
    // (bind.hpp's fast_array: no buffer protocol, no DLPack), anything else converted as a
    // nanobind int8 array argument converts it (TypeError where it cannot be).
    i64 go(double dt, double damping, i64 row, nb::handle warm, bool canonical, i64 max_iter) {
        WarmView wv;
        B2 converted;  // a converted warm array, held for the call
        if (!warm.is_none()) {
            FastArray fa;
            if (fast_array(warm.ptr(), 'b', false, fa) && fa.c_contiguous && fa.ndim == 2) {
                wv = WarmView{reinterpret_cast<const i8*>(fa.data), static_cast<i64>(fa.shape[0]),
                              static_cast<i64>(fa.shape[1]), true};
            } else {
                if (!nb::try_cast(warm, converted))
                    throw nb::type_error("Kernel.go: warm must be None or an int8 array of shape (L, nv)");
                wv = WarmView{converted.data(), dim(converted, 0), dim(converted, 1), true};
            }
        }
        return step_from_sources(dt, damping, row, wv, canonical, max_iter);
    }

    // go(dt, damping, row, None, false, max_iter): the cold step of IKSolver.step's plain
    // lane, bound with positional arguments only (nanobind's simple dispatch: a call from
    // Python converts four arguments, not six through the named-argument path; about 200
    // instructions less per step).
    i64 go_cold(double dt, double damping, i64 row, i64 max_iter) {
        return step_from_sources(dt, damping, row, WarmView{}, false, max_iter);
    }

    // A warm array of go(): its int8 entries and shape (given false: None, a cold start).
    struct WarmView {
        const i8* p = nullptr;
        i64 rows = 0, cols = 0;
        bool given = false;
    };

    // go() and go_cold() once the warm view is made: the sources' values into the slots, then
    // solve_into (-1 where they do not load).
    // (always inlined: a call costs the plain lane about 270 instructions a step)
    __attribute__((always_inline)) i64 step_from_sources(double dt, double damping, i64 row, const WarmView& wv,
                                                         bool canonical, i64 max_iter) {
        last_row_ = -1;
        pass_row_ = -1;
        if (!load_sources(dt, damping)) return -1;
        return solve_into(row, wv, canonical, max_iter);
    }

    // go()'s step once its values are in the slots.
    i64 solve_into(i64 row, const WarmView& warm, bool canonical, i64 max_iter) {
        require(attached_.has_value(), "Kernel.go: no MjData attached (Kernel.attach)");
        require(out_.has_value(), "Kernel.go: no outputs attached (Kernel.attach_out)");
        Outputs& o = *out_;
        require(row >= 0 && row < o.K, "Kernel.go: row out of range");
        make_jacobians();
        const diffik::FusedArgs& a = go_args_;  // fill_poses of the attached arrays (attach)
        const i8* w = nullptr;
        if (warm.given) {
            require(warm.rows == L_ && warm.cols == n_, "Kernel.go: warm must have shape (L, nv)");
            w = warm.p;
        } else {
            w = cold_sets(L_ * n_);
        }
        diffik::StepResult& r = step_;  // kept: its vectors' storage reused
        diffik::fused_step_into(a, max_iter, MatRefT<const i8>(w, L_, n_), canonical, ws_, scratch_, r, true);
        if (r.code != diffik::OK) return r.code;
        write_answers(row, r, n_, "Kernel.go: unexpected answer shapes");
        std::memcpy(o.active.data() + row * L_ * n_, r.active.data(), L_ * n_);
        last_row_ = row;
        return r.code;
    }

    // A step's answers (dq, v, info, the attached qpos, the deferred sigmas' records) into
    // row `row` of the attached outputs, its active sets checked to have `cols` columns.
    void write_answers(i64 row, const diffik::StepResult& r, i64 cols, const char* shapes) {
        Outputs& o = *out_;
        write_deferred(row);
        require(r.active_cols == cols && static_cast<i64>(r.d.size()) == n_ &&
                    static_cast<i64>(r.info.size()) == 9 * L_,
                shapes);
        const Vec& v = r.v_is_d ? r.d : r.v;
        std::memcpy(o.d.data() + row * n_, r.d.data(), sizeof(double) * n_);
        std::memcpy(o.v.data() + row * n_, v.data(), sizeof(double) * n_);
        std::memcpy(o.info.data() + row * 9 * L_, r.info.data(), sizeof(double) * 9 * L_);
        std::memcpy(o.qpos.data() + row * nq_, attached_->qpos.data(), sizeof(double) * nq_);
    }

    // The gathered step's cascade in one call, as go() makes it, on the values load_sources()
    // has put into the slots: the Jacobians (make_jacobians), then the tasks' rows, the box
    // and the general rows G (p, nv), h (p,) from a cold start (as run() with zero active
    // sets and canonical false), the answers (dq, v, info, qpos, the deferred sigmas' records)
    // written into row `row` of the attached outputs. Returns (code, active): active (L, nv + p)
    // int8, a new array, where the code is OK, else None (nothing written).
    nb::tuple rows_into(i64 row, const In2& G, const In1& h, i64 max_iter) {
        require(out_.has_value(), "Kernel.rows_into: no outputs attached (Kernel.attach_out)");
        require(row >= 0 && row < out_->K, "Kernel.rows_into: row out of range");
        require(dim(G, 1) == n_ && dim(h, 0) == dim(G, 0), "Kernel.rows_into: G must be (p, nv) and h (p,)");
        last_row_ = -1;
        pass_row_ = -1;
        diffik::FusedArgs a = attached_args(G, h);
        make_jacobians();
        const i64 p = dim(G, 0), cols = n_ + p;
        diffik::StepResult& r = step_;  // kept: its vectors' storage reused
        diffik::fused_step_into(a, max_iter, MatRefT<const i8>(cold_sets(L_ * cols), L_, cols), false, ws_, scratch_,
                                r, true);
        if (r.code != diffik::OK) return nb::make_tuple(r.code, nb::none());
        write_answers(row, r, cols, "Kernel.rows_into: unexpected answer shapes");
        BVec active(r.active.begin(), r.active.end());
        return nb::make_tuple(r.code, to_numpy(std::move(active), {static_cast<size_t>(L_), static_cast<size_t>(cols)}));
    }

    // The arrays of a second MjData (MuJoCo's kinematics at q (+) dq), held for correct()
    // as attach() holds the step's.
    void attach_aux(nb::object owner, const In1& qpos, const In2& sx, const In2& sm, const In2& x,
                    const In2& xm, const In2& gx, const In2& gm, const In2& subtree_com) {
        check_poses(qpos, sx, sm, x, xm, gx, gm, subtree_com);
        aux_ = Attached{std::move(owner), qpos, sx, sm, x, xm, gx, gm, subtree_com};
    }

    // A correction pass's targets (correct(), correct_run()): on the first pass after the step
    // (first), the held levels (diffik::held_levels, from the step's answer d and info (9, L)),
    // the uncorrected targets b0 and the weighted errors at q; then, where a level is held
    // (any), the held levels' targets in a.b shifted by their remainder at the attached aux
    // MjData (shift: the rows of tasks that supply their own, or None). Returns OK, or
    // NOT_FINITE where a shifted target is not finite.
    i64 shift_held(diffik::FusedArgs& a, const double* d, const double* info, bool first,
                   const std::optional<In1>& shift, bool& any) {
        const i64 M = dim(b_, 0);
        if (first) {
            b0_.resize(static_cast<size_t>(M));
            for (i64 r = 0; r < M; ++r) b0_[static_cast<size_t>(r)] = a.b[r];
            diffik::held_levels(a, CVecRef(b0_), d, info, held_);
            we0_.assign(static_cast<size_t>(M), 0.0);
            diffik::weighted_errors(a, held_, we0_.data(), scratch_.local);
        }
        require(static_cast<i64>(b0_.size()) == M && static_cast<i64>(held_.size()) == L_,
                "Kernel: a correction pass before the first after its step");
        any = false;
        for (char c : held_) any = any || c != 0;
        if (!any) return diffik::OK;
        const Attached& u = *aux_;
        const diffik::FusedArgs x = fill_poses(u.qpos, u.sx, u.sm, u.x, u.xm, u.gx, u.gm, u.subtree_com);
        we1_.assign(static_cast<size_t>(M), 0.0);
        diffik::weighted_errors(x, held_, we1_.data(), scratch_.local);
        return diffik::shift_targets(a, held_, CVecRef(b0_), we0_.data(), we1_.data(),
                                     shift ? shift->data() : nullptr, d)
                   ? diffik::OK
                   : diffik::NOT_FINITE;
    }

    // One second-order correction pass of the step go() last wrote into row `row`
    // (qpik.StepOptions.correction_passes): the first pass decides the held levels
    // (diffik::held_levels) and keeps the uncorrected targets b0 and weighted errors at q;
    // each pass shifts the held levels' targets by the remainder at the attached aux MjData
    // (the caller's kinematics at q (+) dq of the row's answer) and solves the cascade again
    // on the same rows, regularisation and box (from a cold start), its answers written
    // over the row's (qpos kept). shift (M,): the remainders' errors of the rows of tasks that supply their
    // own (NaN elsewhere), or None. Returns the code (OK: the row holds the corrected step;
    // else the caller answers by the QP path).
    i64 correct(i64 row, const std::optional<In1>& shift, i64 max_iter) {
        require(attached_.has_value() && aux_.has_value() && out_.has_value(),
                "Kernel.correct: attach, attach_aux and attach_out first");
        require(row >= 0 && row == last_row_, "Kernel.correct: row is not the answer of the last go()");
        const i64 M = dim(b_, 0);
        if (shift) require(dim(*shift, 0) == M, "Kernel.correct: shift must have shape (M,)");
        Outputs& o = *out_;
        const Attached& t = *attached_;
        diffik::FusedArgs a = fill_poses(t.qpos, t.sx, t.sm, t.x, t.xm, t.gx, t.gm, t.subtree_com);
        double* d = o.d.data() + row * n_;
        const bool first = pass_row_ != row;  // the first pass after go()
        pass_row_ = row;
        bool any = false;
        const i64 shifted = shift_held(a, d, o.info.data() + row * 9 * L_, first, shift, any);
        if (!any) return diffik::OK;  // no level held: the step stands
        if (shifted != diffik::OK) return shifted;
        // A cold start: the same answer as from the row's active sets (the cascade ends each
        // level in its canonical re-solve), and fewer instructions (Talos: 2.15M per pass
        // against 2.39M warm).
        diffik::StepResult& r = step_;
        diffik::solve_rows_step_into(a, max_iter, MatRefT<const i8>(cold_sets(L_ * n_), L_, n_), false, ws_,
                                     scratch_, r, true);
        if (r.code != diffik::OK) return r.code;
        require(r.active_cols == n_ && static_cast<i64>(r.d.size()) == n_ &&
                    static_cast<i64>(r.info.size()) == 9 * L_,
                "Kernel.correct: unexpected answer shapes");
        std::memcpy(d, r.d.data(), sizeof(double) * n_);
        std::memcpy(o.v.data() + row * n_, r.v.data(), sizeof(double) * n_);
        std::memcpy(o.info.data() + row * 9 * L_, r.info.data(), sizeof(double) * 9 * L_);
        std::memcpy(o.active.data() + row * L_ * n_, r.active.data(), L_ * n_);
        write_deferred(row);
        return r.code;
    }

    // One second-order correction pass of the step run() last made (the gathered step, its
    // general rows G, h passed again: the same arrays), as correct() makes one of go()'s: from
    // that step's answer d (nv,) and info (9, L), or the previous pass's; first: the first pass
    // after run() (the held levels, the uncorrected targets b0 and the weighted errors at q
    // decided then). The cascade solved again on the same rows and box with the held levels'
    // targets shifted (from a cold start, each level's sigma resolved). Returns None where no
    // level is held (the step stands), else (code, d, v, info, active) as run() does (OK: the
    // corrected step; else the caller answers by the QP path).
    nb::object correct_run(const In2& G, const In1& h, const In1& d_in, const In2& info_in, bool first,
                           const std::optional<In1>& shift, i64 max_iter) {
        require(attached_.has_value() && aux_.has_value(), "Kernel.correct_run: attach and attach_aux first");
        const i64 M = dim(b_, 0);
        require(dim(d_in, 0) == n_ && dim(info_in, 0) == 9 && dim(info_in, 1) == L_,
                "Kernel.correct_run: d must have shape (nv,), info (9, L)");
        if (shift) require(dim(*shift, 0) == M, "Kernel.correct_run: shift must have shape (M,)");
        diffik::FusedArgs a = attached_args(G, h);
        pass_row_ = -1;  // (correct()'s passes start again after a go())
        bool any = false;
        const i64 shifted = shift_held(a, d_in.data(), info_in.data(), first, shift, any);
        if (!any) return nb::none();  // no level held: the step stands
        auto failed = [](i64 code) { return nb::make_tuple(code, nb::none(), nb::none(), nb::none(), nb::none()); };
        if (shifted != diffik::OK) return failed(shifted);
        const i64 p = a.G.rows;
        BVec cold(static_cast<size_t>(L_ * (n_ + p)), 0);
        diffik::StepResult r;
        diffik::solve_rows_step_into(a, max_iter, MatRefT<const i8>(cold.data(), L_, n_ + p), false, ws_,
                                     scratch_, r, false);
        if (r.code != diffik::OK) return failed(r.code);
        if (r.v_is_d) r.v = r.d;
        require(static_cast<i64>(r.d.size()) == n_ && static_cast<i64>(r.v.size()) == n_ &&
                    static_cast<i64>(r.info.size()) == 9 * L_ &&
                    static_cast<i64>(r.active.size()) == L_ * r.active_cols,
                "Kernel.correct_run: unexpected answer shapes");
        return nb::cast(result_tuple(r, L_));
    }

    // The step's deferred records (the cascade's, or none: the couplings' path and a step
    // that did not solve leave them empty) into row `row` of the defer output.
    void write_deferred(i64 row) {
        auto& o = *out_;
        const Vec& deferred = scratch_.cascade.deferred;
        const i64 width = dim(o.defer, 1);
        require(static_cast<i64>(deferred.size()) <= width, "Kernel: deferred records past defer_width");
        double* drow = o.defer.data() + row * width;
        if (deferred.empty()) std::fill(drow, drow + L_, -1.0);
        else std::memcpy(drow, deferred.data(), sizeof(double) * deferred.size());
    }

    // The largest CascadeResult::deferred of a step: L header entries, and per level k of m_k
    // rows a record of 5 entries and a matrix of at most min(nv, m_k) m_k entries (R's rows, or
    // the last level's M when it has more rows than directions).
    i64 defer_width() const {
        const i64* s = starts_.data.data();
        i64 width = L_;
        for (i64 k = 0; k < L_; ++k) {
            const i64 m = s[k + 1] - s[k];
            width += 5 + std::min(n_, m) * m;
        }
        return width;
    }

    i64 levels() const { return L_; }
    i64 nv() const { return n_; }
    // The cascade's storage, kept from one step to the next (sizes only grow).
    core::Workspace& workspace() const { return ws_; }
    // The rows' and boxes' storage, kept likewise.
    diffik::Scratch& scratch() const { return scratch_; }

  private:
    Out2 A_;
    Out1 b_, w_;
    Held3 jac_;
    Held2 frame_data_, posture_data_, cfg_data_;
    Held1 vel_limit_, settings_;
    Held3 com_jac_;
    Held2 com_data_;
    Held3 rel_jac_;
    Held2 rel_data_;
    std::optional<Held1> user_mu_;
    std::optional<Held2> lin_const_, lin_data_, ke_data_, eq_data_;
    IndexCopy eq_map_;
    struct Efc {
        In1 J, pos;
        Int32In1 type, id, rownnz, rowadr, colind;
    };
    std::optional<Efc> efc_;  // (the views attach_efc holds: kept alive with their MjData)
    tasks::EfcRows efc_rows_;
    struct Attached {
        nb::object owner;
        In1 qpos;
        In2 sx, sm, x, xm, gx, gm, subtree_com;
    };
    std::optional<Attached> attached_, aux_;
    diffik::FusedArgs go_args_;  // fill_poses of attached_'s arrays (attach)
    i64 last_row_ = -1, pass_row_ = -1;  // go()'s last answered row; correct()'s first pass
    Vec b0_, we0_, we1_;
    std::vector<char> held_;
    struct Slot {
        View1 view;
        double* p = nullptr;
        i64 size = 0, stride = 1;
        bool scalar = false;
    };
    std::vector<Slot> slots_;
    struct Source {
        nb::object obj, name, inner;
        bool gain = false;  // a gain (name "gain"): loaded only where it is in [0, 1]
        std::vector<i64> pick;  // entries of a vector value (empty: the value as it is)
    };
    std::vector<Source> sources_;
    struct Guard {
        nb::object obj, name, value;
    };
    std::vector<Guard> guards_;
    struct Outputs {
        Out2 d, v;
        Out3 info;
        Act3 active;
        Out2 qpos;
        Out2 defer;
        i64 K = 0;
    };
    std::optional<Outputs> out_;
    // Zero active sets (a cold start), never written: at least as many as the largest start
    // asked for (cold_sets).
    BVec cold_;
    const i8* cold_sets(i64 size) {
        if (static_cast<i64>(cold_.size()) < size) cold_.assign(static_cast<size_t>(size), 0);
        return cold_.data();
    }
    std::optional<Out3> jac_w_;
    DofChains frame_chains_;
    struct Chains {
        In2 cdof, subtree_com;
    };
    std::optional<Chains> cdof_;
    // The kinetic-energy tasks' M(q) (nv * nv; NaN until made), the tree it is made on, the
    // attached cdof and cinert (in Chains' two fields) and the composite inertias' scratch.
    Vec inertia_;
    std::vector<i64> dof_threshold_;  // (set_dof_thresholds; empty: not set)
    bind::OwnedTree tree_;
    std::optional<Chains> inertia_in_;
    Vec crb_;
    std::optional<Out3> rel_w_;
    DofChains rel_chains_;
    std::optional<Out3> com_w_;
    IndexCopy com_point_, com_root_;
    std::vector<double> com_scale_;
    i64 max_com_body_ = -1;
    i64 nq_ = 0, n_ = 0, L_ = 0;
    IndexCopy starts_, tasks_, frames_, rel_frames_, com_body_, posture_map_, cfg_dof_, cfg_qadr_,
        vel_dof_, lin_starts_;
    i64 max_id_[3] = {-1, -1, -1};
    i64 max_body_ = -1;
    mutable core::Workspace ws_;
    mutable diffik::Scratch scratch_;
    mutable diffik::StepResult step_;  // go()'s and correct()'s answer (every field written by each)
};

// The cascade on a call's arguments (Kernel.step, run, run_deferred): the step's result,
// v = d where it has no velocity. defer: as fused_step_into's (the sigmas the cascade may
// defer left NaN, their records in the scratch's cascade.deferred).
diffik::StepResult kernel_step(const Kernel& k, const diffik::FusedArgs& a, const B2& warm, bool canonical,
                               i64 max_iter, bool defer) {
    const i64 n = k.nv(), L = k.levels(), p = a.G.rows;
    require(dim(warm, 0) == L && dim(warm, 1) == n + p, "Kernel.step: warm must have shape (L, nv + p)");
    diffik::StepResult r;
    diffik::fused_step_into(a, max_iter, MatRefT<const i8>(warm.data(), L, n + p), canonical, k.workspace(),
                            k.scratch(), r, defer);
    if (r.v_is_d) r.v = r.d;
    return r;
}


// Kernel.step / Kernel.run.
auto step_tuple(const Kernel& k, const diffik::FusedArgs& a, const B2& warm, bool canonical,
                i64 max_iter) {
    diffik::StepResult r = kernel_step(k, a, warm, canonical, max_iter, false);
    return result_tuple(r, k.levels());
}

// Kernel.run_deferred: run()'s step with the sigma of each level whose rank the cascade
// proves full left NaN in info (as go() leaves it; the same answer, statuses and
// certificates), and the cascade's records of them (core::CascadeResult::deferred, as go()
// writes them into its defer output: qpik.core.kernels.resolve_sigma resolves them).
auto step_tuple_deferred(const Kernel& k, const diffik::FusedArgs& a, const B2& warm, bool canonical,
                         i64 max_iter) {
    diffik::StepResult r = kernel_step(k, a, warm, canonical, max_iter, true);
    Vec deferred = r.code == diffik::OK ? k.scratch().cascade.deferred : Vec();
    return std::tuple_cat(result_tuple(r, k.levels()), std::make_tuple(to_numpy(std::move(deferred))));
}

}  // namespace

void bind_diffik(nb::module_& m) {
    nb::class_<Kernel>(m, "Kernel",
                       "The one-call step of one stack: its structure and (held by reference) "
                       "its float arrays; see qpik.diffik.compiled.CompiledPlan.")
        .def(nb::init<Out2, Out1, Out1, const I1&, const I2&, Held3, const I2&, Held2, Held2,
                      const I2&, const I1&, const I1&, Held2, const I1&, Held1, Held1, Held3,
                      const I1&, Held2, Held3, const I2&, Held2, i64, std::optional<Held1>,
                      std::optional<I1>, std::optional<Held2>, std::optional<Held2>, std::optional<Held2>,
                      std::optional<I2>, std::optional<Held2>>(),
             nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("w").noconvert(),
             nb::arg("starts"), nb::arg("tasks"), nb::arg("jac").noconvert(), nb::arg("frames"),
             nb::arg("frame_data").noconvert(), nb::arg("posture_data").noconvert(),
             nb::arg("posture_map"), nb::arg("cfg_dof"), nb::arg("cfg_qadr"),
             nb::arg("cfg_data").noconvert(), nb::arg("vel_dof"), nb::arg("vel_limit").noconvert(),
             nb::arg("settings").noconvert(), nb::arg("com_jac").noconvert(), nb::arg("com_body"),
             nb::arg("com_data").noconvert(), nb::arg("rel_jac").noconvert(), nb::arg("rel_frames"),
             nb::arg("rel_data").noconvert(), nb::arg("nq"),
             nb::arg("user_mu").noconvert() = nb::none(), nb::arg("lin_starts") = nb::none(),
             nb::arg("lin_const").noconvert() = nb::none(),
             nb::arg("lin_data").noconvert() = nb::none(), nb::arg("ke_data").noconvert() = nb::none(),
             nb::arg("eq_map") = nb::none(), nb::arg("eq_data").noconvert() = nb::none())
        .def(
            "step",
            [](Kernel& k, In1 qpos, In2 sx, In2 sm, In2 x, In2 xm, In2 gx, In2 gm, In2 subtree_com,
               In2 G, In1 h, B2 warm, bool canonical, i64 max_iter) {
                diffik::FusedArgs a = k.args(qpos, sx, sm, x, xm, gx, gm, subtree_com, G, h);
                return step_tuple(k, a, warm, canonical, max_iter);
            },
            nb::arg("qpos"), nb::arg("site_xpos"), nb::arg("site_xmat"), nb::arg("xpos"),
            nb::arg("xmat"), nb::arg("geom_xpos"), nb::arg("geom_xmat"), nb::arg("subtree_com"),
            nb::arg("G"), nb::arg("h"), nb::arg("warm"), nb::arg("canonical"), nb::arg("max_iter"),
            "Rows of every task, the limits' box and general rows G dq <= h, and the cascade; "
            "returns (code, dq, v, info (9, L): residual, sigma, lambda^2, status, iterations, "
            "then the certificate's four measures, active (L, nv + p) int8).")
        .def("attach", &Kernel::attach, nb::arg("owner"), nb::arg("qpos"), nb::arg("site_xpos"),
             nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"), nb::arg("geom_xpos"),
             nb::arg("geom_xmat"), nb::arg("subtree_com"),
             "Hold one MjData's arrays (step's first 8 arguments, checked once; owner, the MjData, "
             "kept alive with them) for run().")
        .def(
            "run",
            [](Kernel& k, In2 G, In1 h, B2 warm, bool canonical, i64 max_iter) {
                diffik::FusedArgs a = k.attached_args(G, h);
                return step_tuple(k, a, warm, canonical, max_iter);
            },
            nb::arg("G"), nb::arg("h"), nb::arg("warm"), nb::arg("canonical"), nb::arg("max_iter"),
            "step() on the attached MjData's arrays (Kernel.attach): step's last 5 arguments, the "
            "same answer.")
        .def(
            "run_deferred",
            [](Kernel& k, In2 G, In1 h, B2 warm, bool canonical, i64 max_iter) {
                diffik::FusedArgs a = k.attached_args(G, h);
                return step_tuple_deferred(k, a, warm, canonical, max_iter);
            },
            nb::arg("G"), nb::arg("h"), nb::arg("warm"), nb::arg("canonical"), nb::arg("max_iter"),
            "run() with the sigma of each level whose rank the cascade proves full left NaN in "
            "info (as go() defers it; the same answer, statuses and certificates), and the "
            "records that resolve them: (code, d, v, info, active, deferred).")
        .def("attach_aux", &Kernel::attach_aux, nb::arg("owner"), nb::arg("qpos"),
             nb::arg("site_xpos"), nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"),
             nb::arg("geom_xpos"), nb::arg("geom_xmat"), nb::arg("subtree_com"),
             "Hold a second MjData's arrays (as attach) for correct(): the kinematics at q (+) dq.")
        .def("correct", &Kernel::correct, nb::arg("row"), nb::arg("shift").none(),
             nb::arg("max_iter"),
             "One second-order correction pass of go()'s last answer (row `row`): the held "
             "levels' targets shifted by their remainder at the aux MjData, the cascade solved "
             "again, its answers written over the row; returns the code. shift: (M,) the "
             "remainders of the rows of tasks that supply their own (NaN elsewhere), or None.")
        .def("correct_run", &Kernel::correct_run, nb::arg("G"), nb::arg("h"), nb::arg("d"),
             nb::arg("info"), nb::arg("first"), nb::arg("shift").none(), nb::arg("max_iter"),
             "One second-order correction pass of run()'s last step (its G, h again), from its "
             "answer d and info or the previous pass's; first: the first pass after run(). None "
             "where no level is held, else (code, d, v, info, active) as run().")
        .def("set_slots", &Kernel::set_slots, nb::arg("views"), nb::arg("scalar"),
             "The slots go()'s values are written into: writable float64 vectors (views of the "
             "plan's arrays, held), scalar[i] True where slot i takes one number for all its entries.")
        .def("set_chains", &Kernel::set_chains, nb::arg("jac").noconvert(), nb::arg("starts"),
             nb::arg("dofs"), nb::arg("roots"),
             "go() computes the frames' Jacobians itself (as MuJoCo's mj_jac): each frame's dof "
             "chain dofs[starts[f]:starts[f+1]] and its body's root roots[f]; jac the kernel's.")
        .def("set_rel_chains", &Kernel::set_rel_chains, nb::arg("rel_jac").noconvert(), nb::arg("starts"),
             nb::arg("dofs"), nb::arg("roots"),
             "go() computes the relative-frame tasks' Jacobians too (as MuJoCo's mj_jac): rel_jac the "
             "kernel's (R, 12, nv), read as 2R frames (each task's frame, then its root frame), frame k's "
             "dof chain dofs[starts[k]:starts[k+1]] and its body's root roots[k].")
        .def("attach_chains", &Kernel::attach_chains, nb::arg("cdof"), nb::arg("subtree_com"),
             "The attached MjData's cdof (nv, 6) and subtree_com (nbody, 3), for set_chains.")
        .def("set_inertia", &Kernel::set_inertia, nb::arg("body_parent"), nb::arg("dof_body"),
             nb::arg("dof_parent"), nb::arg("armature"), nb::arg("fixed"),
             "The model's tree (int64 body_parent (nbody,), dof_body, dof_parent (nv,); armature and fixed "
             "(nv,): a simple dof's constant diagonal dof_M0, NaN for the others) "
             "whence each step makes the kinetic-energy tasks' inertia matrix M(q).")
        .def("attach_efc", &Kernel::attach_efc, nb::arg("efc_J"), nb::arg("efc_pos"), nb::arg("efc_type"),
             nb::arg("efc_id"), nb::arg("efc_J_rownnz"), nb::arg("efc_J_rowadr"), nb::arg("efc_J_colind"),
             nb::arg("sparse"),
             "The MjData's constraint rows (mj_makeConstraint) the equality-constraint tasks read at the next "
             "steps (attach again after each update: their views change with nefc).")
        .def("set_dof_thresholds", &Kernel::set_dof_thresholds, nb::arg("threshold"),
             "Each dof's threshold (nv,) for the manipulability tasks whose frame a ball or free joint moves "
             "(qpik.model.gradients.motion_chain).")
        .def("attach_inertia", &Kernel::attach_inertia, nb::arg("cdof"), nb::arg("cinert"),
             "The MjData's cdof (nv, 6) and cinert (nbody, 10) (mj_comPos) that M(q) is made from.")
        .def("set_com_chains", &Kernel::set_com_chains, nb::arg("com_jac").noconvert(), nb::arg("point"),
             nb::arg("root"), nb::arg("scale"),
             "Have go() compute the CoM tasks' Jacobians into com_jac (the kernel's own (C, 3, nv) array) from "
             "the MjData attach_chains holds: point, root (C, nv) int64 and scale (C, nv), each task's per-dof "
             "chain (qpik.model.com.subtree_com_chain).")
        .def("attach_out", &Kernel::attach_out, nb::arg("d").noconvert(), nb::arg("v").noconvert(),
             nb::arg("info").noconvert(), nb::arg("active").noconvert(), nb::arg("qpos").noconvert(),
             nb::arg("defer").noconvert(),
             "Hold the rows go() writes into: d, v (K, nv), info (K, 9, L), active (K, L, nv) "
             "int8, qpos (K, nq), defer (K, defer_width): the records of the levels whose sigma "
             "go() deferred (info's sigma NaN there; qpik.core.kernels.resolve_sigma(info[1], defer)).")
        .def_prop_ro("defer_width", &Kernel::defer_width,
                     "The width of attach_out's defer rows (L header entries, then the records).")
        .def("set_guards", &Kernel::set_guards, nb::arg("guards"),
             "The task attributes the plan was built from, per guard (object, name, value): "
             "go() declines a step (-1) where getattr(object, name) is neither value nor equal "
             "to it; the objects are held.")
        .def("load_limits", &Kernel::load_limits, nb::arg("first"),
             "The limits' values of the gathered step: sources first.. (set_sources; the position "
             "limits' bounds and gains, the velocity limits' speeds) loaded into their slots and "
             "checked (bounds with a range, gains in (0, 1], speeds >= 0); False where one is not "
             "taken as it is or fails (the caller writes them its general way, which reports it).")
        .def("make_jacobians", &Kernel::make_jacobians,
             "The Jacobians of every chain set (set_chains, set_rel_chains, set_com_chains) into "
             "the plan's arrays, from the attached cdof and subtree_com (attach_chains), as go() "
             "makes them: bitwise MuJoCo's.")
        .def("load_sources", &Kernel::load_sources, nb::arg("dt"), nb::arg("damping"),
             "The values go() reads before it solves, for the gathered step (run): dt and damping "
             "into the first two slots, every source's value into its slot (the tasks' targets, "
             "costs, gains and LM damping, the limits' values, checked) and the guards checked; "
             "False where one is not taken as it is (the caller then writes them its general "
             "way, which reports it).")
        .def("set_sources", &Kernel::set_sources, nb::arg("sources"),
             "Where go() reads the values of the slots after the first two (dt, damping): "
             "per slot (object, name), (object, name, inner name) or (object, name, indices), "
             "getattr(object, name), getattr(getattr(object, name), inner name) or "
             "getattr(object, name)[indices] (a float64 vector's entries, indices a list of "
             "ints); the objects are held.")
        .def("go", &Kernel::go, nb::arg("dt"), nb::arg("damping"), nb::arg("row"),
             nb::arg("warm").none(), nb::arg("canonical"), nb::arg("max_iter"),
             "run() without general rows: dt and damping as the first two slots' values and the "
             "others read from the sources (set_sources) by the kernel, then the answers (dq, v, "
             "info, active, the step's qpos) written into row `row` of the attached outputs; "
             "returns -1 (nothing solved) where a value is not what its slot takes as it is, is "
             "None or raised (the caller's general way reports it), else the step's code (answers "
             "written only when OK). warm: None for a cold start.")
        .def("rows_into", &Kernel::rows_into, nb::arg("row"), nb::arg("G"), nb::arg("h"), nb::arg("max_iter"),
             "After load_sources(): the Jacobians, the rows, the box, the general rows G dq <= h "
             "(p, nv) and the cascade from a cold start (run()'s answer), the answers written into "
             "row `row` of the attached outputs as go() writes them; returns (code, active (L, nv + "
             "p) int8) where the code is OK, else (code, None).")
        .def("go_cold", &Kernel::go_cold,
             "go_cold(dt, damping, row, max_iter): go(dt, damping, row, None, False, max_iter) "
             "(a cold start), its arguments positional only (the plain lane of IKSolver.step).")
        .def(
            "rows",
            [](Kernel& k, In1 qpos, In2 sx, In2 sm, In2 x, In2 xm, In2 gx, In2 gm, In2 subtree_com,
               In2 G, In1 h) {
                diffik::FusedArgs a = k.args(qpos, sx, sm, x, xm, gx, gm, subtree_com, G, h);
                diffik::RowsResult r = diffik::fused_rows(a);
                return std::make_tuple(r.code, to_numpy(std::move(r.reg)), to_numpy(std::move(r.box.lb)),
                                       to_numpy(std::move(r.box.ub)));
            },
            nb::arg("qpos"), nb::arg("site_xpos"), nb::arg("site_xmat"), nb::arg("xpos"),
            nb::arg("xmat"), nb::arg("geom_xpos"), nb::arg("geom_xmat"), nb::arg("subtree_com"),
            nb::arg("G"), nb::arg("h"),
            "The hierarchy's rows and limits without solving it: fills A, b, w; returns (code, "
            "reg, lb, ub).");

    m.attr("OK") = static_cast<i64>(diffik::OK);
    m.attr("NOT_FINITE") = static_cast<i64>(diffik::NOT_FINITE);
    m.attr("CONFLICT") = static_cast<i64>(diffik::CONFLICT);
    m.attr("UNSETTLED") = static_cast<i64>(diffik::UNSETTLED);

    m.def(
        "boxes",
        [](In1 qpos, double dt, I1 cfg_dof, In1 cfg_lower, In1 cfg_upper, In1 cfg_gain, I1 vel_dof,
           In1 vel_limit, i64 n) {
            require(n >= 0 && n <= dim(qpos, 0), "boxes: n (the number of dofs) must be in [0, len(qpos)]");
            const i64 E = dim(cfg_dof, 0);
            require(dim(cfg_lower, 0) == E && dim(cfg_upper, 0) == E && dim(cfg_gain, 0) == E,
                    "boxes: cfg_lower, cfg_upper and cfg_gain must have len(cfg_dof) entries");
            require(dim(vel_limit, 0) == dim(vel_dof, 0), "boxes: vel_limit must have len(vel_dof) entries");
            const i64 dofs = std::min(n, dim(qpos, 0));
            check_dofs(ivec(cfg_dof), dofs, "boxes: a cfg_dof entry is out of range");
            check_dofs(ivec(vel_dof), n, "boxes: a vel_dof entry is out of range");
            diffik::Box box = diffik::boxes(cvec(qpos), dt, ivec(cfg_dof), cfg_lower.data(),
                                            cfg_upper.data(), cfg_gain.data(), 1, ivec(vel_dof),
                                            cvec(vel_limit), n);
            return std::make_tuple(to_numpy(std::move(box.lb)), to_numpy(std::move(box.ub)), box.bad);
        },
        nb::arg("qpos"), nb::arg("dt"), nb::arg("cfg_dof"), nb::arg("cfg_lower"), nb::arg("cfg_upper"),
        nb::arg("cfg_gain"), nb::arg("vel_dof"), nb::arg("vel_limit"), nb::arg("n"),
        "The limits' merged box (lb, ub, i): position bounds gain (upper - q), -gain (q - lower), "
        "velocity bounds |dq| <= v_max dt; i >= 0 the first dof whose velocity bounds conflict.");

    m.def(
        "fused_rows",
        [](Out2 A, Out1 b, Out1 w, I1 starts, I2 tasks, In3 jac, I2 frames, In2 site_xpos,
           In2 site_xmat, In2 xpos, In2 xmat, In2 geom_xpos, In2 geom_xmat, In2 frame_data,
           In1 qpos, In2 posture_data, I1 cfg_dof, In2 cfg_data, I1 vel_dof, In1 vel_limit,
           In1 settings) {
            diffik::FusedArgs a = make_args(A, b, w, starts, tasks, jac, frames, site_xpos, site_xmat,
                                            xpos, xmat, geom_xpos, geom_xmat, frame_data, qpos,
                                            posture_data, cfg_dof, cfg_data, vel_dof, vel_limit,
                                            settings);
            diffik::RowsResult r = diffik::fused_rows(a);
            return std::make_tuple(r.code, to_numpy(std::move(r.reg)), to_numpy(std::move(r.box.lb)),
                                   to_numpy(std::move(r.box.ub)));
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("w").noconvert(),
        nb::arg("starts"), nb::arg("tasks"), nb::arg("jac"), nb::arg("frames"), nb::arg("site_xpos"),
        nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"), nb::arg("geom_xpos"),
        nb::arg("geom_xmat"), nb::arg("frame_data"), nb::arg("qpos"), nb::arg("posture_data"),
        nb::arg("cfg_dof"), nb::arg("cfg_data"), nb::arg("vel_dof"), nb::arg("vel_limit"),
        nb::arg("settings"),
        "The hierarchy's rows and limits without solving it: fills A, b, w and returns (code, "
        "reg, lb, ub); see qpik.diffik.compiled for the arguments.");

    m.def(
        "fused_step",
        [](Out2 A, Out1 b, Out1 w, I1 starts, I2 tasks, In3 jac, I2 frames, In2 site_xpos,
           In2 site_xmat, In2 xpos, In2 xmat, In2 geom_xpos, In2 geom_xmat, In2 frame_data,
           In1 qpos, In2 posture_data, I1 cfg_dof, In2 cfg_data, I1 vel_dof, In1 vel_limit,
           In1 settings, i64 max_iter, B2 warm, bool canonical) {
            diffik::FusedArgs a = make_args(A, b, w, starts, tasks, jac, frames, site_xpos, site_xmat,
                                            xpos, xmat, geom_xpos, geom_xmat, frame_data, qpos,
                                            posture_data, cfg_dof, cfg_data, vel_dof, vel_limit,
                                            settings);
            const i64 n = a.qpos.n, L = a.starts.n - 1;
            require(dim(warm, 0) == L && dim(warm, 1) == n, "fused_step: warm must have shape (L, nv)");
            core::Workspace ws;  // a one-off step: storage of its own
            diffik::StepResult r = diffik::fused_step(
                a, max_iter, MatRefT<const i8>(warm.data(), L, n), canonical, ws);
            if (r.v_is_d) r.v = r.d;
            const size_t L_ = static_cast<size_t>(L), cols = static_cast<size_t>(r.active_cols);
            return std::make_tuple(r.code, to_numpy(std::move(r.d)), to_numpy(std::move(r.v)),
                                   to_numpy(std::move(r.info), {9, L_}),
                                   to_numpy(std::move(r.active), {L_, cols}));
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("w").noconvert(),
        nb::arg("starts"), nb::arg("tasks"), nb::arg("jac"), nb::arg("frames"), nb::arg("site_xpos"),
        nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"), nb::arg("geom_xpos"),
        nb::arg("geom_xmat"), nb::arg("frame_data"), nb::arg("qpos"), nb::arg("posture_data"),
        nb::arg("cfg_dof"), nb::arg("cfg_data"), nb::arg("vel_dof"), nb::arg("vel_limit"),
        nb::arg("settings"), nb::arg("max_iter"), nb::arg("warm"), nb::arg("canonical"),
        "Rows of every task, the limits' box and the cascade in one call; returns (code, dq, v, "
        "info (9, L), active (L, nv) int8). See qpik.diffik.compiled.");
}

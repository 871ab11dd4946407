// The one-call differential IK step (qpik.diffik.compiled builds its plan): every task's
// rows (frame tasks by mink's SE(3)
// arithmetic, model/se3.hpp; postures on hinge/slide joints), the limits' box, and the
// cascade (core::solve_cascade; a first level of pair couplings, a mimic, by the exact fast
// path of couple.hpp). Anything unusual (a non-finite row, conflicting limits, a
// level whose active set did not settle) is reported by a code, for the QP path.
//
// The caller (the bindings) guarantees the shapes and that every index is in range; see
// FusedArgs.
#pragma once

#include <limits>
#include <vector>

#include "../common.hpp"
#include "../detmath.hpp"
#include "../core/cascade.hpp"
#include "../tasks/frame.hpp"
#include "../tasks/pose.hpp"
#include "../tasks/joint_limits.hpp"
#include "../tasks/linear.hpp"
#include "../tasks/look_at.hpp"
#include "../tasks/axis_align.hpp"
#include "../tasks/kinetic.hpp"
#include "../tasks/manipulability.hpp"
#include "../tasks/equality.hpp"
#include "couple.hpp"

namespace qpik::diffik {

// Result codes: anything but OK sends the step to the general path.
enum Code : i64 { OK = 0, NOT_FINITE = 1, CONFLICT = 2, UNSETTLED = 3 };
// Entries of `settings`.
enum Setting : i64 {
    DT = 0, DAMPING = 1, THRESHOLD = 2, MAX_DAMPING = 3, ERROR_SCALE = 4, RANK_TOL = 5, TOL = 6,
    LOWER_TRUST = 7  // DampingLaw.lower_trust (0: off; see core::detail::trust_box)
};
constexpr i64 kSettings = 7;  // (LOWER_TRUST optional: 0 where absent)
constexpr double kPi = 3.14159265358979323846;  // MuJoCo's mjPI
constexpr i64 kFrameData = 15;  // target wxyz_xyz (7), cost (6), gain, lm_damping
// A world-frame pose task's row of frame_data (kinds POSE_*; the table then has at least
// this many columns): target position (3), rotation (row-major 9), cost (6), gain, lm_damping.
constexpr i64 kPoseData = tasks::kPoseTarget + 8;

// The arguments of fused_rows / fused_step (views on the plan's arrays and MuJoCo's).
// A (M, n), b, w (M,); starts (L + 1,); tasks (T, 4): kind (TaskKind), index,
// level, first row; jac (F, 6, n) contiguous; frames (F, 2): kind (0 site, 1 body, 2 geom),
// id; the six pose arrays (*, 3) / (*, 9); frame_data (F, 15); qpos (n,); posture_data
// (P, nq + n + 2); cfg_dof (E,), cfg_data (E, 3) rows (lower, upper, gain); vel_dof,
// vel_limit (V,); settings (7,).
struct FusedArgs {
    MatRef A;
    VecRef b;
    VecRef w;
    VecRefT<const i64> starts;
    MatRefT<const i64> tasks;
    const double* jac = nullptr;
    MatRefT<const i64> frames;
    CMatRef site_xpos, site_xmat, xpos, xmat, geom_xpos, geom_xmat;
    CMatRef frame_data;
    CVecRef qpos;
    CMatRef posture_data;
    VecRefT<const i64> cfg_dof;
    CMatRef cfg_data;
    VecRefT<const i64> vel_dof;
    CVecRef vel_limit;
    CVecRef settings;
    // The extended plan's arguments (qpik.diffik.compiled.Kernel); empty in the legacy layout.
    // posture_map (nv, 2): per dof, kind (0 hinge/slide, 1 free joint: zero row, 2 first
    // dof of a ball joint, 3 its other dofs) and qpos address; empty: dof i is qpos[i].
    MatRefT<const i64> posture_map;
    VecRefT<const i64> cfg_qadr;  // (E,) qpos address of each position-limited dof; empty: cfg_dof
    // CoM tasks (kind 2): com_jac (C, 3, nv), com_body (C,) rows of subtree_com (nbody, 3),
    // com_data (C, 8): target (3) [m, world], cost (3), gain, lm_damping.
    const double* com_jac = nullptr;
    VecRefT<const i64> com_body;
    CMatRef subtree_com;
    CMatRef com_data;
    // Relative frame tasks (kind 3): rel_jac (R, 12, nv) the frame's then the root's
    // world-aligned Jacobians; rel_frames (R, 4) frame kind, id, root kind, id; rel_data
    // (R, 15): target in the root frame wxyz_xyz (7), cost (6), gain, lm_damping.
    const double* rel_jac = nullptr;
    MatRefT<const i64> rel_frames;
    CMatRef rel_data;
    // General limit rows G dq <= h (p, nv), (p,), held at every level.
    CMatRef G = CMatRef(nullptr, 0, 0);
    CVecRef h;
    // Tasks whose rows the caller supplies (kind 5, ROWS): their rows of A, b, w are written
    // before the call (from the task's own methods) and left as they are; user_mu (U,) holds
    // each one's LM term, added to its level's regularisation in the stack's task order.
    CVecRef user_mu;
    // Linear tasks (kind 6, LINEAR: qpik's CouplingTask of linear couplings): task i has the
    // stacked rows r0:r1 = lin_starts[i]:lin_starts[i + 1] of lin_const (K, nv + nq + 1), each
    // row its constant Jacobian row (nv), its coefficients over qpos (nq) and its offset
    // (tasks/linear.hpp), and the columns r0:r1 of lin_data (3, K): its rows' costs, then its
    // gain and lm_damping in column r0.
    VecRefT<const i64> lin_starts;
    CMatRef lin_const = CMatRef(nullptr, 0, 0);
    CMatRef lin_data = CMatRef(nullptr, 0, 0);
    // Kinetic-energy tasks (kind 13, KINETIC): ke_data (E, 2) each one's cost and 1 / dt^2
    // [1/s^2] (its own dt, mink's inv_dt_sq); inertia (nv, nv) the joint-space inertia
    // matrix M(q) (model/inertia.hpp, made by the kernel from the attached MjData's cinert).
    CMatRef ke_data = CMatRef(nullptr, 0, 0);
    const double* inertia = nullptr;
    // Each frame's dofs as mj_jac visits them (leaf first), frame f's dofs
    // chain_dofs[chain_starts[f]:chain_starts[f + 1]] (Kernel.set_chains; empty: not set).
    VecRefT<const i64> chain_starts, chain_dofs;
    // Each dof's threshold for manipulability tasks on chains with ball or free joints
    // (model::hessian_weights_any; Kernel.set_dof_thresholds; null: not set).
    const i64* dof_threshold = nullptr;
    // Equality-constraint tasks (kind 15, EQUALITY): eq_map (Q, neq + 1) each one's planned
    // rows, then its position of each equality of the model (-1: not its); eq_data (Q, neq
    // + 2) its costs by position, gain, LM damping; efc the MjData's constraint rows
    // (Kernel.attach_efc; null: not attached, every such task declines).
    MatRefT<const i64> eq_map;
    CMatRef eq_data = CMatRef(nullptr, 0, 0);
    const tasks::EfcRows* efc = nullptr;
};

// Task kinds of FusedArgs::tasks.
enum TaskKind : i64 {
    FRAME = 0, POSTURE = 1, COM = 2, RELATIVE = 3, DAMPING_TASK = 4, ROWS = 5, LINEAR = 6,
    // qpik's world-frame pose tasks (tasks/pose.hpp; a frame of the frames table): part
    // kind - POSE_BASE (1 position, 2 orientation, 3 both)
    POSE_POSITION = 7, POSE_ORIENTATION = 8, POSE_FULL = 9,
    // qpik's JointLimitDistanceTask (tasks/joint_limits.hpp): one row; its constants in row
    // lin_starts[index] of lin_const: half range by dof (0: not counted), mid / half by qpos
    // address, then n (the scalar joints counted); its cost, gain and LM damping in lin_data
    JOINT_LIMITS = 10,
    // mink's (and qpik's) LookAtTask and AxisAlignTask (tasks/look_at.hpp, axis_align.hpp):
    // three rows; a frame of the frames table, its data row as a pose task's (kPoseData):
    // target 0:3 (target_pos, target_dir), axis 3:6, cost at kPoseTarget, gain and LM
    // damping after its six cost entries
    LOOK_AT = 11, AXIS_ALIGN = 12,
    // mink's (and qpik's) KineticEnergyRegularizationTask (tasks/kinetic.hpp): nv rows, A =
    // L^T of (cost / dt^2) M = L L^T, b = 0, weights 1, no LM term; ke_data row `index`
    KINETIC = 13,
    // qpik's ManipulabilityTask (tasks/manipulability.hpp): one row; a frame of the frames
    // table on a chain of hinges and slides, its data row as a pose task's: the number of
    // rows picked at 0 and their indices into [v; omega] from 1 (at most 11), its cost at
    // kPoseTarget, at kPoseTarget + 1 a flag: 1 where a ball or free joint moves the frame
    // (dof_threshold's Hessian), gain and LM damping after its six cost entries
    MANIPULABILITY = 14,
    // mink's (and qpik's) EqualityConstraintTask (tasks/equality.hpp): its planned rows, from
    // the attached MjData's equality constraint rows; eq_map / eq_data row `index`
    EQUALITY = 15
};
// LookAtTask's floor on |r| (qpik.diffik.rows._EPS: the same rows as the QP path's).
constexpr double kLookAtEps = 1e-10;
constexpr i64 POSE_BASE = 6;
inline bool is_pose(i64 kind) { return kind >= POSE_POSITION && kind <= POSE_FULL; }
// A frame or linear task's kind with this bit added: its rows as mink's equality
// constraints (qpik.diffik.constraints.FrameConstraint and DofConstraint, a level above the
// tasks in qpik.solve_ik): its rows (costs ones, LM damping 0), then each row scaled to unit
// norm (unit_rows), with weight kUndampedWeight and no LM term.
constexpr i64 UNIT_ROWS = 32;
// The weight of such a row (qpik.diffik.constraints.UNDAMPED_WEIGHT, 2^-40): the damping law
// reads the level's singular values 2^40 times theirs and never damps it.
constexpr double kUndampedWeight = 0x1p-40;

// Whether the kernel's correction passes (weighted_errors, shift_targets) cover a task kind:
// not a constraint's unit rows, a look-at or an axis-align task's (CompiledPlan._correct
// leaves such a plan's correction to the QP path: qpik.diffik.layout.corrected_kinds).
inline bool corrected_kind(i64 kind) {
    return (kind & UNIT_ROWS) == 0 && kind != LOOK_AT && kind != AXIS_ALIGN && kind != KINETIC &&
           kind != MANIPULABILITY && kind != EQUALITY;
}

// Rows row:row+size of A and b scaled to unit norm, as qpik._engine.tasks.unit_rows scales
// J and -gain e (s = 1 / |A_r|, |A_r| by its squares summed in order from +0; 1 for a zero
// row; b_r = (1.0 b_r) s, unit_rows' (-gain e) s with gain -1: the same bits).
inline void unit_rows_in_place(MatRef A, double* b, i64 row, i64 size) {
    const i64 n = A.cols;
    for (i64 r = row; r < row + size; ++r) {
        double* ar = A.row(r);
        double sq = 0.0;
        for (i64 c = 0; c < n; ++c) sq += ar[c] * ar[c];
        const double norm = std::sqrt(sq);
        const double s = norm > 0.0 ? 1.0 / norm : 1.0;
        for (i64 c = 0; c < n; ++c) ar[c] = ar[c] * s;
        b[r] = (1.0 * b[r]) * s;
    }
}
constexpr i64 kComData = 8;  // target (3), cost (3), gain, lm_damping
enum PostureDof : i64 { SCALAR_DOF = 0, FREE_DOF = 1, BALL_FIRST = 2, BALL_OTHER = 3 };

// Rows row:row+6 of a frame task at pose (xpos, xmat) with target (wxyz_xyz):
// frame_error_jlog then frame_rows_into; returns its LM term.
inline double frame_rows(MatRef A, double* b, i64 row, CMatRef jac, const double* xpos,
                         const double* xmat, const double* target, const double* cost, double gain,
                         double lm_damping, double* local) {
    double error[6], jlog[36];
    tasks::frame_error_jlog(xmat, xpos, target, error, jlog);
    return tasks::frame_rows_into(A, b, row, jac, xmat, jlog, error, cost, gain, lm_damping, local);
}

// Row i of diag(cost) scaled: cost * 0.0 off the diagonal (computed once: the products of
// zeros, whose sign follows cost's) and cost * diag at column i, over nv columns.
inline void cost_row(double* Ai, i64 nv, i64 i, double cost, double diag) {
    const double off = cost * 0.0;
    const core::simd::v2d o = core::simd::splat(off);
    i64 j = 0;
    for (; j + 2 <= nv; j += 2) core::simd::store(Ai + j, o);
    if (j < nv) Ai[j] = off;
    Ai[i] = cost * diag;
}

// Rows row:row+nv of a posture task on hinge/slide joints: A = diag(cost), b = cost (-gain
// (q - q*)); returns lm_damping |b|^2.
inline double posture_rows(MatRef A, double* b, i64 row, CVecRef qpos, const double* target,
                           const double* cost, double gain, double lm_damping) {
    const i64 nv = qpos.n;
    double mu = 0.0;
    for (i64 i = 0; i < nv; ++i) {
        cost_row(&A(row + i, 0), nv, i, cost[i], 1.0);
        b[row + i] = cost[i] * (-gain * (qpos[i] - target[i]));
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

// MuJoCo's mju_normalize4 / mju_normalize3 (mjMINVAL = 1e-15); return the norm.
inline double mj_normalize4(double* v) {
    const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
    if (norm < 1e-15) {
        v[0] = 1.0;
        v[1] = v[2] = v[3] = 0.0;
    } else if (std::fabs(norm - 1.0) > 1e-15) {
        const double inv = 1.0 / norm;
        for (int i = 0; i < 4; ++i) v[i] *= inv;
    }
    return norm;
}
inline double mj_normalize3(double* v) {
    const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (norm < 1e-15) {
        v[0] = 1.0;
        v[1] = v[2] = 0.0;
    } else {
        const double inv = 1.0 / norm;
        for (int i = 0; i < 3; ++i) v[i] *= inv;
    }
    return norm;
}

// A ball joint's part of mj_differentiatePos(qpos1 = qb, qpos2 = qa, dt = 1): the rotation
// vector [rad] of qb^-1 qa (both normalised first), the shorter way round.
inline void ball_difference(double* res, const double* qa_raw, const double* qb_raw) {
    double qa[4] = {qa_raw[0], qa_raw[1], qa_raw[2], qa_raw[3]};
    double qb[4] = {qb_raw[0], qb_raw[1], qb_raw[2], qb_raw[3]};
    mj_normalize4(qa);
    mj_normalize4(qb);
    const double neg[4] = {qb[0], -qb[1], -qb[2], -qb[3]};
    double dif[4];
    model::se3_detail::quat_mul(dif, neg, qa);
    double axis[3] = {dif[1], dif[2], dif[3]};
    const double sin_half = mj_normalize3(axis);
    double speed = 2.0 * dm::atan2(sin_half, dif[0]);
    if (speed > kPi) speed -= 2.0 * kPi;
    res[0] = axis[0] * speed;
    res[1] = axis[1] * speed;
    res[2] = axis[2] * speed;
}

// Rows row:row+nv of mink's PostureTask / DampingTask on any joints (map: see
// FusedArgs::posture_map): A = diag(cost) J (J the identity with the free joints' columns
// zeroed), b = cost (-gain e), e = q (-) q* by mj_differentiatePos (free joints' entries
// zero; all zero for a damping task). Returns lm_damping |b|^2.
inline double posture_rows_map(MatRef A, double* b, i64 row, CVecRef qpos,
                               MatRefT<const i64> map, const double* target, const double* cost,
                               double gain, double lm_damping, bool zero_error, double* e) {
    const i64 nv = map.rows;
    for (i64 i = 0; i < nv; ++i) {
        const i64 kind = map(i, 0), adr = map(i, 1);
        if (zero_error || kind == FREE_DOF) {
            e[i] = 0.0;
        } else if (kind == SCALAR_DOF) {
            e[i] = qpos[adr] - target[adr];
        } else if (kind == BALL_FIRST) {
            ball_difference(e + i, qpos.p + adr, target + adr);
        }
    }
    double mu = 0.0;
    for (i64 i = 0; i < nv; ++i) {
        const double diag = map(i, 0) == FREE_DOF ? 0.0 : 1.0;
        cost_row(&A(row + i, 0), nv, i, cost[i], diag);
        b[row + i] = cost[i] * (-gain * e[i]);
        mu += b[row + i] * b[row + i];
    }
    return lm_damping * mu;
}

struct Box {
    Vec lb, ub;
    i64 bad = -1;  // the first dof whose hard bounds conflict, else -1
};

// The limits' box, as qpik.IKSolver._limit_rows builds it: position bounds gain (upper -
// q), -gain (q - lower) (recoverable), velocity bounds |dq| <= v_max dt (hard), merged by
// core::merge_boxes.
// Position limit e: lower[e * stride], upper[e * stride], gain[e * stride]. Every dof index
// is in [0, min(n, qpos.n)).
// cfg_qadr (E,) the qpos address of each entry (empty: the dof index; hinge/slide only).
// The storage of boxes_into (sizes only grow; every entry written before it is read).
struct BoxScratch {
    Vec hard_lb, hard_ub, pos_lb, pos_ub;
};

inline void boxes_into(CVecRef qpos, double dt, VecRefT<const i64> cfg_dof, const double* cfg_lower,
                       const double* cfg_upper, const double* cfg_gain, i64 stride,
                       VecRefT<const i64> vel_dof, CVecRef vel_limit, i64 n,
                       VecRefT<const i64> cfg_qadr, BoxScratch& s, Box& box) {
    const size_t m = static_cast<size_t>(n);
    fill_as(s.hard_lb, m, -kInf);
    fill_as(s.hard_ub, m, kInf);
    fill_as(s.pos_lb, m, -kInf);
    fill_as(s.pos_ub, m, kInf);
    Vec &hard_lb = s.hard_lb, &hard_ub = s.hard_ub, &pos_lb = s.pos_lb, &pos_ub = s.pos_ub;
    for (i64 e = 0; e < cfg_dof.n; ++e) {
        const i64 i = cfg_dof[e];
        const double q = qpos[cfg_qadr.n ? cfg_qadr[e] : i];
        const double g = cfg_gain[e * stride];
        const double upper = g * (cfg_upper[e * stride] - q);
        const double lower = -g * (q - cfg_lower[e * stride]);
        if (lower > pos_lb[i]) pos_lb[i] = lower;
        if (upper < pos_ub[i]) pos_ub[i] = upper;
    }
    for (i64 e = 0; e < vel_dof.n; ++e) {
        const i64 i = vel_dof[e];
        const double bound = vel_limit[e] * dt;
        if (-bound > hard_lb[i]) hard_lb[i] = -bound;
        if (bound < hard_ub[i]) hard_ub[i] = bound;
    }
    box.bad = core::merge_boxes(CVecRef(hard_lb), CVecRef(hard_ub), CVecRef(pos_lb),
                                CVecRef(pos_ub), box.lb, box.ub);
}

inline Box boxes(CVecRef qpos, double dt, VecRefT<const i64> cfg_dof, const double* cfg_lower,
                 const double* cfg_upper, const double* cfg_gain, i64 stride,
                 VecRefT<const i64> vel_dof, CVecRef vel_limit, i64 n,
                 VecRefT<const i64> cfg_qadr = VecRefT<const i64>()) {
    BoxScratch s;
    Box box;
    boxes_into(qpos, dt, cfg_dof, cfg_lower, cfg_upper, cfg_gain, stride, vel_dof, vel_limit, n,
               cfg_qadr, s, box);
    return box;
}

// The pose (xpos, xmat) of frame (kind 0 site, 1 body, 2 geom; id).
inline void frame_pose(const FusedArgs& a, i64 kind, i64 fid, const double*& pos,
                       const double*& mat) {
    if (kind == 0) {
        pos = a.site_xpos.row(fid);
        mat = a.site_xmat.row(fid);
    } else if (kind == 1) {
        pos = a.xpos.row(fid);
        mat = a.xmat.row(fid);
    } else {
        pos = a.geom_xpos.row(fid);
        mat = a.geom_xmat.row(fid);
    }
}

// The joint-limit distance task's row `row` of A, b (tasks/joint_limits.hpp) from its
// constants in row r0 of lin_const (half range by dof, 0 where the dof is not a limited
// joint's; mid / half by qpos address; n) and its cost, gain and LM damping in column r0 of
// lin_data, the limited joints in dof order (a scalar dof's qpos address from posture_map).
// Returns its LM term.
inline auto joint_limits_slots(const FusedArgs& a, i64 r0) {
    const i64 n = a.A.cols;
    const double* c = a.lin_const.row(r0);
    return [&a, c, n](i64 k, i64& adr, i64& dof, double& half, double& moh) {
        if (!(c[k] > 0.0)) return false;
        dof = k;
        adr = a.posture_map(k, 1);
        half = c[k];
        moh = c[n + adr];
        return true;
    };
}

inline double joint_limits_row(const FusedArgs& a, i64 r0, i64 row) {
    const i64 n = a.A.cols, nq = a.qpos.n;
    return tasks::joint_limit_distance_row(a.A, a.b.p, row, a.qpos.p, n, joint_limits_slots(a, r0),
                                           a.lin_const(r0, n + nq), a.lin_data(0, r0), a.lin_data(1, r0),
                                           a.lin_data(2, r0));
}

// Its w alone (A and b untouched).
inline double joint_limits_value(const FusedArgs& a, i64 r0) {
    const i64 n = a.A.cols, nq = a.qpos.n;
    return tasks::joint_limit_distance_value(a.qpos.p, n, joint_limits_slots(a, r0), a.lin_const(r0, n + nq));
}

// A task's rows row:row+size that the kernel does not make at this step (a kinetic-energy
// task's H not factored, an equality task's rows not its planned count, a manipulability
// task without its chain): zero, with a NaN target in the first, which sends the step to
// the QP path (fused_rows_into: NOT_FINITE), whose rows the task's own routine makes.
inline void decline_rows(const FusedArgs& a, i64 row, i64 size) {
    for (i64 r = row; r < row + size; ++r) {
        for (i64 c = 0; c < a.A.cols; ++c) a.A(r, c) = 0.0;
        a.b[r] = 0.0;
    }
    if (size > 0) a.b[row] = std::numeric_limits<double>::quiet_NaN();
}

// A manipulability task's row (frame i's Jacobian, its data row `data`: the rows picked, gain
// and LM damping) into row `row` of A and b; returns its LM term. Without the frame's chain
// (never set) or with more rows picked than its data row holds: a NaN target (the QP path).
inline double manipulability_task_row(const FusedArgs& a, i64 i, const double* data, double cost, Vec& local,
                                      i64 row) {
    const i64 n = a.A.cols;
    const i64 m = static_cast<i64>(data[0]);
    const bool any_joint = data[tasks::kPoseTarget + 1] != 0.0;
    if (a.chain_starts.n <= i + 1 || m < 0 || m > 11 || (any_joint && a.dof_threshold == nullptr)) {
        decline_rows(a, row, 1);
        return 0.0;
    }
    i64 idx[11];
    for (i64 r = 0; r < m; ++r) idx[r] = static_cast<i64>(data[1 + r]);
    const i64 first = a.chain_starts[i], count = a.chain_starts[i + 1] - first;
    const i64* leaf_last = count > 0 ? a.chain_dofs.p + first + count - 1 : a.chain_dofs.p;
    const size_t need = static_cast<size_t>(tasks::manipulability_scratch(m, n) + n);
    if (local.size() < need) local.resize(need);
    double* de = local.data();
    const double e = tasks::inverse_manipulability(a.jac + i * 6 * n, n, idx, m, leaf_last, count, -1,
                                                   local.data() + n, de, nullptr, nullptr,
                                                   any_joint ? a.dof_threshold : nullptr);
    const double gain = data[tasks::kPoseTarget + 6], lm = data[tasks::kPoseTarget + 7];
    return tasks::manipulability_row(e, de, n, cost, gain, lm, a.A.row(row), a.b.p + row);
}

// Fill every task's rows of A, b, w; each level's LM term sum lm_damping |b_task|^2 into
// reg (L); local: scratch (sizes only grow). diag (M): per row of A, the column of its
// diagonal entry where a posture or damping task wrote it last (cost_row: every other entry
// the same value), else -1.
inline void assemble_rows(const FusedArgs& a, i64 L, Vec& reg, Vec& local, IVec& diag) {
    const i64 n = a.A.cols;
    zero_fill(reg, static_cast<size_t>(L));
    fill_as(diag, static_cast<size_t>(a.A.rows), i64{-1});
    if (local.size() < static_cast<size_t>(19 * n)) local.resize(static_cast<size_t>(19 * n));
    for (i64 t = 0; t < a.tasks.rows; ++t) {
        const i64 kind = a.tasks(t, 0);
        const i64 i = a.tasks(t, 1);
        const i64 row = a.tasks(t, 3);
        // A frame task's rows (its data row's costs, gain and LM damping) and their LM term.
        auto frame_task_rows = [&]() {
            const double* pos;
            const double* mat;
            frame_pose(a, a.frames(i, 0), a.frames(i, 1), pos, mat);
            const double* data = a.frame_data.row(i);
            CMatRef jac(a.jac + i * 6 * n, 6, n);
            return frame_rows(a.A, a.b.p, row, jac, pos, mat, data, data + 7, data[13], data[14], local.data());
        };
        // A linear task's rows (lin_data's costs and gain; LM damping lm) and their LM term.
        auto linear_task_rows = [&](double lm) {
            const i64 r0 = a.lin_starts[i], k = a.lin_starts[i + 1] - r0;
            const i64 stride = a.lin_const.stride;
            const double* c = a.lin_const.row(r0);
            if (static_cast<i64>(local.size()) < k) local.resize(static_cast<size_t>(k));
            return tasks::linear_rows_into(a.A, a.b.p, row, CMatRef(c, k, n, stride),
                                           CMatRef(c + n, k, a.lin_const.cols - n, stride), a.qpos.p,
                                           a.lin_data.row(0) + r0, a.lin_data(1, r0), lm, local.data());
        };
        if ((kind & UNIT_ROWS) != 0) {  // a constraint: its rows scaled to unit norm, no LM term
            i64 k = 6;
            if (kind == (FRAME | UNIT_ROWS)) {
                frame_task_rows();  // (its costs ones, its LM damping 0)
            } else {                // LINEAR | UNIT_ROWS: mink's DofFreezingTask
                k = a.lin_starts[i + 1] - a.lin_starts[i];
                linear_task_rows(0.0);
            }
            unit_rows_in_place(a.A, a.b.p, row, k);
            for (i64 r = 0; r < k; ++r) diag[static_cast<size_t>(row + r)] = -1;
            for (i64 r = 0; r < k; ++r) a.w[row + r] = kUndampedWeight;
            continue;
        }
        if (kind == KINETIC) {  // (cost / dt^2) M factored; declined: a NaN target, the QP path
            const double* data = a.ke_data.row(i);
            if (static_cast<i64>(local.size()) < n * n) local.resize(static_cast<size_t>(n * n));
            if (!tasks::kinetic_rows_into(a.A, a.b.p, row, a.inertia, n, data[0] * data[1], local.data()))
                decline_rows(a, row, n);  // (H not factored here: the QP path's rows)
            for (i64 r = 0; r < n; ++r) diag[static_cast<size_t>(row + r)] = -1;
            for (i64 r = 0; r < n; ++r) a.w[row + r] = 1.0;
            continue;
        }
        if (kind == EQUALITY) {  // MuJoCo's rows; not its planned count: a NaN target, the QP path
            const i64 planned = a.eq_map(i, 0), neq = a.eq_map.cols - 1, cols = a.eq_data.cols;
            const double* data = a.eq_data.row(i);
            double mu_t = 0.0;
            const i64 k = a.efc == nullptr ? -1
                                           : tasks::equality_rows_into(a.A, a.b.p, a.w.p, row, planned, *a.efc,
                                                                       a.eq_map.row(i) + 1, neq, data,
                                                                       data[cols - 2], data[cols - 1], mu_t);
            if (k != planned) {
                decline_rows(a, row, planned);
                for (i64 r = row; r < row + planned; ++r) a.w[r] = 1.0;
                mu_t = 0.0;
            }
            for (i64 r = 0; r < planned; ++r) diag[static_cast<size_t>(row + r)] = -1;
            reg[a.tasks(t, 2)] += mu_t;
            continue;
        }
        if (kind == ROWS) {  // rows supplied by the task itself: only its LM term here
            reg[a.tasks(t, 2)] += a.user_mu[i];
            continue;
        }
        double mu;
        const double* cost;
        i64 size;
        if (kind == JOINT_LIMITS) {
            const i64 r0 = a.lin_starts[i];
            mu = joint_limits_row(a, r0, row);
            a.w[row] = a.lin_data(0, r0);
            diag[static_cast<size_t>(row)] = -1;
            reg[a.tasks(t, 2)] += mu;
            continue;
        }
        if (kind == LINEAR) {
            const i64 r0 = a.lin_starts[i], k = a.lin_starts[i + 1] - r0;
            cost = a.lin_data.row(0) + r0;
            mu = linear_task_rows(a.lin_data(2, r0));
            for (i64 r = 0; r < k; ++r) a.w[row + r] = cost[r];
            for (i64 r = 0; r < k; ++r) diag[static_cast<size_t>(row + r)] = -1;
            reg[a.tasks(t, 2)] += mu;
            continue;
        }
        if (kind == FRAME) {
            cost = a.frame_data.row(i) + 7;
            mu = frame_task_rows();
            size = 6;
        } else if (is_pose(kind)) {
            const double* pos;
            const double* mat;
            frame_pose(a, a.frames(i, 0), a.frames(i, 1), pos, mat);
            const double* data = a.frame_data.row(i);
            const i64 part = kind - POSE_BASE;
            cost = data + tasks::kPoseTarget;
            CMatRef jac(a.jac + i * 6 * n, 6, n);
            mu = tasks::pose_rows_into(a.A, a.b.p, row, jac, pos, mat, data, part, cost,
                                       data[tasks::kPoseTarget + 6], data[tasks::kPoseTarget + 7]);
            size = tasks::pose_part_rows(part);
        } else if (kind == LOOK_AT || kind == AXIS_ALIGN) {
            const double* pos;
            const double* mat;
            frame_pose(a, a.frames(i, 0), a.frames(i, 1), pos, mat);
            const double* data = a.frame_data.row(i);
            cost = data + tasks::kPoseTarget;
            const double gain = data[tasks::kPoseTarget + 6], lm = data[tasks::kPoseTarget + 7];
            const double* jac = a.jac + i * 6 * n;  // (6, n): jacp, then jacr
            double* rows = local.data();            // (3, n), then into A's rows
            mu = kind == LOOK_AT ? tasks::look_at_residual(jac, n, mat, pos, data, data + 3, cost, gain, lm,
                                                           kLookAtEps, rows, a.b.p + row)
                                 : tasks::axis_align_residual(jac + 3 * n, n, mat, data, data + 3, cost, gain, lm,
                                                              rows, a.b.p + row);
            for (i64 r = 0; r < 3; ++r)
                std::memcpy(a.A.row(row + r), rows + r * n, static_cast<size_t>(n) * sizeof(double));
            size = 3;
        } else if (kind == MANIPULABILITY) {
            const double* data = a.frame_data.row(i);
            cost = data + tasks::kPoseTarget;
            mu = manipulability_task_row(a, i, data, cost[0], local, row);
            size = 1;
        } else if (kind == COM) {
            const double* data = a.com_data.row(i);
            cost = data + 3;
            CMatRef jac(a.com_jac + i * 3 * n, 3, n);
            mu = tasks::com_rows_into(a.A, a.b.p, row, jac, a.subtree_com.row(a.com_body[i]),
                                      data, cost, data[6], data[7]);
            size = 3;
        } else if (kind == RELATIVE) {
            const double *pf, *mf, *pr, *mr;
            frame_pose(a, a.rel_frames(i, 0), a.rel_frames(i, 1), pf, mf);
            frame_pose(a, a.rel_frames(i, 2), a.rel_frames(i, 3), pr, mr);
            const double* data = a.rel_data.row(i);
            cost = data + 7;
            CMatRef jf(a.rel_jac + i * 12 * n, 6, n);
            CMatRef jr(a.rel_jac + i * 12 * n + 6 * n, 6, n);
            mu = tasks::relative_frame_rows_into(a.A, a.b.p, row, jf, mf, pf, jr, mr, pr, data,
                                                 cost, data[13], data[14], local.data());
            size = 6;
        } else {
            const double* data = a.posture_data.row(i);
            const i64 nq = a.posture_data.cols - n - 2;
            cost = data + nq;
            if (a.posture_map.rows == 0 && kind == POSTURE) {
                mu = posture_rows(a.A, a.b.p, row, a.qpos, data, cost, data[nq + n],
                                  data[nq + n + 1]);
            } else {
                mu = posture_rows_map(a.A, a.b.p, row, a.qpos, a.posture_map, data, cost,
                                      data[nq + n], data[nq + n + 1], kind == DAMPING_TASK,
                                      local.data());
            }
            size = n;
            for (i64 r = 0; r < n; ++r) diag[static_cast<size_t>(row + r)] = r;
            for (i64 r = 0; r < size; ++r) a.w[row + r] = cost[r];
            reg[a.tasks(t, 2)] += mu;
            continue;
        }
        for (i64 r = 0; r < size; ++r) diag[static_cast<size_t>(row + r)] = -1;
        for (i64 r = 0; r < size; ++r) a.w[row + r] = cost[r];
        reg[a.tasks(t, 2)] += mu;
    }
}

struct RowsResult {
    i64 code = OK;
    Vec reg;  // (L,)
    Box box;
};

// The storage of a compiled step kept by its kernel from one step to the next (sizes only
// grow; every entry written before it is read): the same bits as fresh storage.
struct Scratch {
    RowsResult rows;
    Vec local;
    IVec diag;  // assemble_rows' posture rows
    BoxScratch box;
    CoupleScratch couple;
    core::CascadeResult cascade;  // the step's cascade result (every field written each step)
};

// Whether the serial sums of fused_rows (of the squares of x, or of its entries) are
// finite, decided without their chain of adds where it can be: every entry finite and
// count * max |x| (squared) at most 1e300 means no partial sum overflows; otherwise the
// sum itself, in its order, decides.
struct FiniteSum {
    bool finite = true;
    double max = 0.0;
    i64 count = 0;
    void add(double x) {
        finite = finite && std::isfinite(x);
        const double m = std::fabs(x);
        max = m > max ? m : max;
        ++count;
    }
    // add() of x[0], ..., x[n - 1] (branch-free: |x| <= DBL_MAX is false for an infinity or
    // a NaN, and a NaN leaves max as add() leaves it; max is read only when all are finite).
    // Two entries at a time: x * 0.0 is +-0 for a finite x and NaN otherwise, so the lanes'
    // sums of them compare equal to 0 exactly when every entry is finite; a lane's max is
    // its entries' (a NaN never wins), and the lanes' maxima combined, the same max
    // wherever every entry is finite (the only place it is read).
    void add_n(const double* x, i64 n) {
        using namespace core::simd;
        // (four entries a pass into two pairs of lanes, then the pairs combined: shorter
        // chains of dependent adds and maxima, the same finite and, where finite, max)
        auto vmax = [](v2d m, v2d acc) {
#if defined(__SSE2__)
            return __builtin_ia32_maxpd(m, acc);  // m > acc ? m : acc, lane by lane
#else
            return m > acc ? m : acc;
#endif
        };
        v2d z2 = splat(0.0), z2b = splat(0.0);
        v2d mx2 = splat(max), mx2b = splat(max);
        i64 t = 0;
        for (; t + 4 <= n; t += 4) {
            const v2d v = load(x + t), w = load(x + t + 2);
            z2 += v * splat(0.0);
            z2b += w * splat(0.0);
            mx2 = vmax(vabs(v), mx2);
            mx2b = vmax(vabs(w), mx2b);
        }
        for (; t + 2 <= n; t += 2) {
            const v2d v = load(x + t);
            z2 += v * splat(0.0);
            mx2 = vmax(vabs(v), mx2);
        }
        z2 += z2b;
        mx2 = vmax(mx2b, mx2);
        bool ok = z2[0] == 0.0 && z2[1] == 0.0;
        double mx = mx2[1] > mx2[0] ? mx2[1] : mx2[0];
        for (; t < n; ++t) {
            const double m = std::fabs(x[t]);
            ok &= m <= std::numeric_limits<double>::max();
            mx = m > mx ? m : mx;
        }
        finite = finite && ok;
        max = mx;
        count += n;
    }
    // add() of x, k times (k >= 1).
    void add_rep(double x, i64 k) {
        const double m = std::fabs(x);
        finite = finite && m <= std::numeric_limits<double>::max();
        max = m > max ? m : max;
        count += k;
    }
    bool safe(bool squares) const {
        if (!finite) return false;
        if (!squares) return max * static_cast<double>(count) <= 1e300;
        return max <= 1e150 && max * max * static_cast<double>(count) <= 1e300;
    }
};

// The hierarchy's rows and limits without solving it into s.rows: fills A, b, w; code OK,
// NOT_FINITE (a row or regularisation) or CONFLICT (velocity-like limits of a dof).
inline i64 fused_rows_into(const FusedArgs& a, Scratch& s) {
    const i64 n = a.A.cols;
    const i64 L = a.starts.n - 1;
    RowsResult& res = s.rows;
    res.code = OK;
    assemble_rows(a, L, res.reg, s.local, s.diag);
    for (i64 k = 0; k < L; ++k) res.reg[k] = a.settings[DAMPING] + res.reg[k];
    const double* cfg = a.cfg_data.p;
    boxes_into(a.qpos, a.settings[DT], a.cfg_dof, cfg, cfg + 1, cfg + 2, a.cfg_data.stride,
               a.vel_dof, a.vel_limit, n, a.cfg_qadr, s.box, res.box);
    FiniteSum bs, ts;
    bs.add_n(a.b.p, a.b.n);
    for (i64 r = 0; r < a.b.n; ++r) {
        const i64 d = s.diag[static_cast<size_t>(r)];
        if (d < 0) {
            // a run of such rows in one add_n where A's rows are contiguous (its finite, max
            // and count: those of one add_n per row)
            i64 e = r + 1;
            if (a.A.stride == n)
                while (e < a.b.n && s.diag[static_cast<size_t>(e)] < 0) ++e;
            ts.add_n(a.A.row(r), (e - r) * n);
            r = e - 1;
        } else {  // a posture row (cost_row): its diagonal entry and n - 1 equal others
            ts.add(a.A(r, d));
            if (n > 1) ts.add_rep(a.A(r, d == 0 ? 1 : 0), n - 1);
        }
    }
    // A's rows square in double precision (their largest at most 1e150, max^2 count at most
    // 1e300: the level's objective and certificate square them), else the general path,
    // which refuses them (InvalidTarget, qpik.diffik.rows._squarable: the same test).
    const bool squarable = ts.safe(true);
    for (i64 r = 0; r < a.G.rows; ++r) {  // general limit rows: finite, or the general path
        ts.add(a.h[r]);
        ts.add_n(a.G.row(r), n);
    }
    bool finite = true;
    if (!bs.safe(true)) {
        double square = 0.0;
        for (i64 r = 0; r < a.b.n; ++r) square += a.b[r] * a.b[r];
        finite = std::isfinite(square);
    }
    if (finite && !ts.safe(false)) {
        double total = 0.0;
        for (i64 r = 0; r < a.b.n; ++r)
            for (i64 j = 0; j < n; ++j) total += a.A(r, j);
        for (i64 r = 0; r < a.G.rows; ++r) {
            total += a.h[r];
            for (i64 j = 0; j < n; ++j) total += a.G(r, j);
        }
        finite = std::isfinite(total);
    }
    double reg_sum = 0.0;
    for (i64 k = 0; k < L; ++k) reg_sum += res.reg[k];
    if (!(finite && std::isfinite(reg_sum) && squarable)) {
        res.code = NOT_FINITE;
    } else if (res.box.bad >= 0) {
        res.code = CONFLICT;
    }
    return res.code;
}

inline RowsResult fused_rows(const FusedArgs& a) {
    Scratch s;
    fused_rows_into(a, s);
    return std::move(s.rows);
}

struct StepResult {
    i64 code = OK;
    Vec d;        // (n,)
    Vec v;        // (n,)
    Vec info;     // (9, L) row-major: residual, sigma, lambda^2, status, iterations, then the
                  // certificate: primal, stationarity, dual, complementarity
    BVec active;  // (L, active_cols) row-major
    i64 active_cols = 0;
    bool v_is_d = false;  // the reference returns d in v's place (the code is not OK then)
};

// Rows of every task, the limits' box and the cascade, in one call. warm (L, n) int8 (the
// previous active sets); see qpik/_fused.py:fused_step.
// ws: the cascade's storage, kept by the caller between steps (core::Workspace).
// s: fused_rows_into's storage, kept by the caller between steps (Scratch).
// The _into forms write into a StepResult the caller keeps (its vectors' storage reused;
// every field written, as a fresh one would hold it).
// defer: a level whose rank the cascade proves full without damping leaves its sigma NaN in
// info, its record in s.cascade.deferred (core::solve_cascade_into's defer_sigma; resolved by
// core::deferred_sigma); else every sigma is computed.
inline void solve_rows_step_into(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                                 bool canonical, core::Workspace& ws, Scratch& s, StepResult& out,
                                 bool defer = false);

inline void fused_step_into(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                            bool canonical, core::Workspace& ws, Scratch& s, StepResult& out,
                            bool defer = false) {
    fused_rows_into(a, s);
    solve_rows_step_into(a, max_iter, warm, canonical, ws, s, out, defer);
}

inline StepResult fused_step(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                             bool canonical, core::Workspace& ws, Scratch& s) {
    StepResult out;
    fused_step_into(a, max_iter, warm, canonical, ws, s, out);
    return out;
}

// The cascade on the rows, regularisation and box that fused_rows_into left in s.rows (A,
// b, w of `a`): fused_step after its rows.
inline void solve_rows_step_into(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                                 bool canonical, core::Workspace& ws, Scratch& s, StepResult& out,
                                 bool defer) {
    const i64 n = a.A.cols;
    const i64 L = a.starts.n - 1;
    const RowsResult& rows = s.rows;
    // a fresh result's fields (d, info and active are written on every path below; v
    // emptied on each path that returns without it)
    out.active_cols = 0;
    out.v_is_d = false;
    out.code = rows.code;
    if (rows.code != OK) {
        out.v.clear();
        out.info.assign(static_cast<size_t>(9 * L), 0.0);
        out.d.assign(static_cast<size_t>(n), 0.0);
        out.v_is_d = true;
        out.active.assign(static_cast<size_t>(L * n), 0);
        out.active_cols = n;
        return;
    }
    const double dt = a.settings[DT];
    const CMatRef G = a.G.rows ? a.G : CMatRef(nullptr, 0, n);
    core::CascadeResult& c = s.cascade;
    c.deferred.clear();  // (couple_step writes it only where it answers)
    const double trust = a.settings.size() > LOWER_TRUST ? a.settings[LOWER_TRUST] : 0.0;
    // A first level of pair couplings (a mimic) by its exact fast path (couple.hpp), else
    // the general cascade.
    if (!couple_step(CMatRef(a.A), CVecRef(a.b), CVecRef(a.w), a.starts, CVecRef(rows.reg),
                     CVecRef(rows.box.lb), CVecRef(rows.box.ub), G, a.h, a.settings[THRESHOLD],
                     a.settings[MAX_DAMPING], a.settings[ERROR_SCALE], a.settings[RANK_TOL],
                     max_iter, a.settings[TOL], warm, canonical, ws, s.couple, c, defer, trust)) {
        core::solve_cascade_into(CMatRef(a.A), CVecRef(a.b), CVecRef(a.w), a.starts,
                                 CVecRef(rows.reg), CVecRef(rows.box.lb), CVecRef(rows.box.ub), G,
                                 a.h, a.settings[THRESHOLD], a.settings[MAX_DAMPING],
                                 a.settings[ERROR_SCALE], a.settings[RANK_TOL], max_iter,
                                 a.settings[TOL], warm, canonical, ws, c, true, false, defer, trust);
    }
    // (c.primal is not read here: the general path leaves it uncomputed)
    out.d.assign(c.dq.begin(), c.dq.end());
    out.active.assign(c.active.begin(), c.active.end());
    out.active_cols = L > 0 ? static_cast<i64>(out.active.size()) / L : n;
    double res_sum = 0.0;
    for (double r : c.residuals) res_sum += r;
    bool finite = std::isfinite(res_sum);
    out.info.resize(static_cast<size_t>(9 * L));  // every entry written below
    for (i64 k = 0; k < L; ++k) {
        if (c.status[k] == core::MAX_ITER || c.status[k] == core::NUMERICAL) {
            out.code = UNSETTLED;
            out.v_is_d = true;
            out.v.clear();
            for (i64 j = 0; j < 9; ++j)  // the levels from k on: zeros (a fresh result's)
                for (i64 q = k; q < L; ++q) out.info[j * L + q] = 0.0;
            return;
        }
        out.info[0 * L + k] = c.residuals[k];
        out.info[1 * L + k] = c.sigma[k];
        out.info[2 * L + k] = c.lam2[k];
        out.info[3 * L + k] = static_cast<double>(c.status[k]);
        out.info[4 * L + k] = static_cast<double>(c.iterations[k]);
        for (i64 j = 0; j < 4; ++j) out.info[(5 + j) * L + k] = c.certificate[4 * k + j];
    }
    out.v.resize(static_cast<size_t>(n));  // every entry written below
    // (d_i^2 and v_i all finite exactly when the sum of their products with 0.0 is 0: each
    // term is +-0 for a finite value and NaN otherwise)
    double zeros = 0.0;
    for (i64 i = 0; i < n; ++i) {
        out.v[i] = out.d[i] / dt;
        zeros += (out.d[i] * out.d[i]) * 0.0 + out.v[i] * 0.0;
    }
    finite = finite && zeros == 0.0;
    if (!finite) {
        out.code = NOT_FINITE;
        out.v_is_d = true;
    }
}

inline StepResult fused_step(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                             bool canonical, core::Workspace& ws) {
    Scratch s;
    return fused_step(a, max_iter, warm, canonical, ws, s);
}

// ---------------------------------------------------------------------------------------
// Second-order correction (qpik.StepOptions.correction_passes): after a step dq at q, the
// held levels' targets are shifted by their tasks' remainder r = e(q (+) dq) - e(q) - J dq
// (b <- b - cost r, A = diag(cost) J unchanged) and the step is solved again on the same
// rows, regularisation and box.

// Whether level k of a step is held (met): status solved and |A_k d - b_k| <= 1e-2 |b_k| +
// 1e-9 |A_k|_F |d| (residual: the cascade's; b: the uncorrected targets).
constexpr double kHeldFraction = 1e-2;
constexpr double kHeldRoundoff = 1e-9;

inline void held_levels(const FusedArgs& a, CVecRef b, const double* d, const double* info,
                        std::vector<char>& held) {
    const i64 n = a.A.cols;
    const i64 L = a.starts.n - 1;
    double dd = 0.0;
    for (i64 j = 0; j < n; ++j) dd += d[j] * d[j];
    held.assign(static_cast<size_t>(L), 0);
    for (i64 k = 0; k < L; ++k) {
        if (info[3 * L + k] != static_cast<double>(core::SOLVED)) continue;
        double bb = 0.0, aa = 0.0;
        for (i64 r = a.starts[k]; r < a.starts[k + 1]; ++r) {
            bb += b[r] * b[r];
            for (i64 j = 0; j < n; ++j) aa += a.A(r, j) * a.A(r, j);
        }
        const double bound = kHeldFraction * std::sqrt(bb) + kHeldRoundoff * std::sqrt(aa) * std::sqrt(dd);
        held[static_cast<size_t>(k)] = info[k] <= bound ? 1 : 0;
    }
}

// cost (.) e, the weighted error of every task the kernel computes on a held level, at the
// poses and qpos of `a`, into we (M,) (rows of other tasks left as they are). The same
// errors as the tasks' rows (fused_rows), without their Jacobians; local: scratch.
inline void weighted_errors(const FusedArgs& a, const std::vector<char>& held, double* we, Vec& local) {
    const i64 n = a.A.cols;
    if (local.size() < static_cast<size_t>(n)) local.resize(static_cast<size_t>(n));
    for (i64 t = 0; t < a.tasks.rows; ++t) {
        const i64 kind = a.tasks(t, 0), i = a.tasks(t, 1), row = a.tasks(t, 3);
        // (a kind corrected_kind leaves out, a constraint's unit rows among them: never
        // corrected here; CompiledPlan declines the correction of a plan that has one: the QP
        // path corrects)
        if (!held[static_cast<size_t>(a.tasks(t, 2))] || kind == ROWS || !corrected_kind(kind)) continue;
        if (kind == FRAME) {
            const double *pos, *mat;
            frame_pose(a, a.frames(i, 0), a.frames(i, 1), pos, mat);
            const double* data = a.frame_data.row(i);
            double frame[7], error[6];
            model::xmat_xpos_to_wxyz_xyz(frame, mat, pos);
            model::se3_rminus(error, data, frame);
            for (i64 r = 0; r < 6; ++r) we[row + r] = data[7 + r] * error[r];
        } else if (is_pose(kind)) {
            const double *pos, *mat;
            frame_pose(a, a.frames(i, 0), a.frames(i, 1), pos, mat);
            const double* data = a.frame_data.row(i);
            double error[6], jinv[9];
            const i64 k = tasks::pose_error(pos, mat, data, kind - POSE_BASE, error, jinv);
            for (i64 r = 0; r < k; ++r) we[row + r] = data[tasks::kPoseTarget + r] * error[r];
        } else if (kind == COM) {
            const double* data = a.com_data.row(i);
            const double* com = a.subtree_com.row(a.com_body[i]);
            for (i64 r = 0; r < 3; ++r) we[row + r] = data[3 + r] * (com[r] - data[r]);
        } else if (kind == RELATIVE) {
            const double *pf, *mf, *pr, *mr;
            frame_pose(a, a.rel_frames(i, 0), a.rel_frames(i, 1), pf, mf);
            frame_pose(a, a.rel_frames(i, 2), a.rel_frames(i, 3), pr, mr);
            const double* data = a.rel_data.row(i);
            double frame[7], root[7], rel[7], error[6];
            model::xmat_xpos_to_wxyz_xyz(frame, mf, pf);
            model::xmat_xpos_to_wxyz_xyz(root, mr, pr);
            model::se3_inverse_multiply(rel, root, frame);
            model::se3_rminus(error, rel, data);
            for (i64 r = 0; r < 6; ++r) we[row + r] = data[7 + r] * error[r];
        } else if (kind == JOINT_LIMITS) {
            // cost * w (the row itself written to scratch: A and b keep the step's)
            const i64 r0 = a.lin_starts[i];
            we[row] = a.lin_data(0, r0) * joint_limits_value(a, r0);
        } else if (kind == LINEAR) {
            const i64 r0 = a.lin_starts[i], k = a.lin_starts[i + 1] - r0;
            const i64 stride = a.lin_const.stride;
            const double* c = a.lin_const.row(r0);
            if (static_cast<i64>(local.size()) < k) local.resize(static_cast<size_t>(k));
            tasks::linear_residual(CMatRef(c + n, k, a.lin_const.cols - n, stride), a.qpos.p, local.data());
            const double* cost = a.lin_data.row(0) + r0;
            for (i64 r = 0; r < k; ++r) we[row + r] = cost[r] * local[r];
        } else {  // POSTURE, DAMPING_TASK
            const double* data = a.posture_data.row(i);
            const i64 nq = a.posture_data.cols - n - 2;
            const double* cost = data + nq;
            double* e = local.data();
            if (a.posture_map.rows == 0) {
                for (i64 r = 0; r < n; ++r) e[r] = kind == DAMPING_TASK ? 0.0 : a.qpos[r] - data[r];
            } else {
                for (i64 r = 0; r < n; ++r) {
                    const i64 dof = a.posture_map(r, 0), adr = a.posture_map(r, 1);
                    if (kind == DAMPING_TASK || dof == FREE_DOF) {
                        e[r] = 0.0;
                    } else if (dof == SCALAR_DOF) {
                        e[r] = a.qpos[adr] - data[adr];
                    } else if (dof == BALL_FIRST) {
                        ball_difference(e + r, a.qpos.p + adr, data + adr);
                    }
                }
            }
            for (i64 r = 0; r < n; ++r) we[row + r] = cost[r] * e[r];
        }
    }
}

// The held levels' rows of b shifted for a correction pass: b[r] = b0[r] - ((we1[r] -
// we0[r]) - (A d)[r]) on the kernel's tasks' rows; on the rows of tasks that supply their
// own (ROWS), shift (M,) when given stands for we1 - we0 where it is finite (the caller
// leaves NaN on every other row: those keep b0 or the kernel's shift). Returns false when a shifted entry is not finite.
inline bool shift_targets(const FusedArgs& a, const std::vector<char>& held, CVecRef b0,
                          const double* we0, const double* we1, const double* shift,
                          const double* d) {
    const i64 n = a.A.cols;
    bool finite = true;
    for (i64 t = 0; t < a.tasks.rows; ++t) {
        const i64 kind = a.tasks(t, 0), i = a.tasks(t, 1), row = a.tasks(t, 3);
        // (a kind the correction does not cover: never corrected, weighted_errors')
        if (!held[static_cast<size_t>(a.tasks(t, 2))] || !corrected_kind(kind)) continue;
        i64 size;
        switch (kind) {
            case FRAME: case RELATIVE: size = 6; break;
            case COM: size = 3; break;
            case POSE_POSITION: case POSE_ORIENTATION: case POSE_FULL: size = tasks::pose_part_rows(kind - POSE_BASE); break;
            case LINEAR: size = a.lin_starts[i + 1] - a.lin_starts[i]; break;
            case JOINT_LIMITS: size = 1; break;
            case ROWS: size = 0; break;  // below, from the caller's shift
            default: size = n;
        }
        for (i64 r = row; r < row + size; ++r) {
            double adq = 0.0;
            for (i64 j = 0; j < n; ++j) adq += a.A(r, j) * d[j];
            a.b[r] = b0[r] - ((we1[r] - we0[r]) - adq);
            finite = finite && std::isfinite(a.b[r]);
        }
    }
    if (shift != nullptr) {  // the caller's rows (ROWS tasks): where shift is finite
        const i64 L = a.starts.n - 1;
        for (i64 k = 0; k < L; ++k) {
            if (!held[static_cast<size_t>(k)]) continue;
            for (i64 r = a.starts[k]; r < a.starts[k + 1]; ++r) {
                if (!std::isfinite(shift[r])) continue;
                double adq = 0.0;
                for (i64 j = 0; j < n; ++j) adq += a.A(r, j) * d[j];
                a.b[r] = b0[r] - (shift[r] - adq);
                finite = finite && std::isfinite(a.b[r]);
            }
        }
    }
    return finite;
}

}  // namespace qpik::diffik

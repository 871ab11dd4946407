// The one-call differential IK step (ported from the kernels of qpik/_fused.py, same
// operations in the same order): every task's rows (frame tasks by mink's SE(3)
// arithmetic, model/se3.hpp; postures on hinge/slide joints), the limits' box, and the
// cascade (core::solve_cascade). Anything unusual (a non-finite row, conflicting limits, a
// level whose active set did not settle) is reported by a code, for the general path.
//
// The caller (the bindings) guarantees the shapes and that every index is in range; see
// FusedArgs.
#pragma once

#include <vector>

#include "../common.hpp"
#include "../core/cascade.hpp"
#include "../tasks/frame.hpp"

namespace qpik::diffik {

// Result codes: anything but OK sends the step to the general path.
enum Code : i64 { OK = 0, NOT_FINITE = 1, CONFLICT = 2, UNSETTLED = 3 };
// Entries of `settings`.
enum Setting : i64 { DT = 0, DAMPING = 1, THRESHOLD = 2, MAX_DAMPING = 3, ERROR_SCALE = 4, RANK_TOL = 5, TOL = 6 };
constexpr i64 kSettings = 7;
constexpr i64 kFrameData = 15;  // target wxyz_xyz (7), cost (6), gain, lm_damping

// The arguments of fused_rows / fused_step (views on the plan's arrays and MuJoCo's).
// A (M, n), b, w (M,); starts (L + 1,); tasks (T, 4): kind (0 frame, 1 posture), index,
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
};

// Rows row:row+6 of a frame task at pose (xpos, xmat) with target (wxyz_xyz):
// frame_error_jlog then frame_rows_into; returns its LM term.
inline double frame_rows(MatRef A, double* b, i64 row, CMatRef jac, const double* xpos,
                         const double* xmat, const double* target, const double* cost, double gain,
                         double lm_damping, double* local) {
    double error[6], jlog[36];
    tasks::frame_error_jlog(xmat, xpos, target, error, jlog);
    return tasks::frame_rows_into(A, b, row, jac, xmat, jlog, error, cost, gain, lm_damping, local);
}

// Rows row:row+nv of a posture task on hinge/slide joints: A = diag(cost), b = cost (-gain
// (q - q*)); returns lm_damping |b|^2.
inline double posture_rows(MatRef A, double* b, i64 row, CVecRef qpos, const double* target,
                           const double* cost, double gain, double lm_damping) {
    const i64 nv = qpos.n;
    double mu = 0.0;
    for (i64 i = 0; i < nv; ++i) {
        for (i64 j = 0; j < nv; ++j) A(row + i, j) = cost[i] * (i == j ? 1.0 : 0.0);
        b[row + i] = cost[i] * (-gain * (qpos[i] - target[i]));
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
inline Box boxes(CVecRef qpos, double dt, VecRefT<const i64> cfg_dof, const double* cfg_lower,
                 const double* cfg_upper, const double* cfg_gain, i64 stride,
                 VecRefT<const i64> vel_dof, CVecRef vel_limit, i64 n) {
    Vec hard_lb(static_cast<size_t>(n), -kInf), hard_ub(static_cast<size_t>(n), kInf);
    Vec pos_lb(static_cast<size_t>(n), -kInf), pos_ub(static_cast<size_t>(n), kInf);
    for (i64 e = 0; e < cfg_dof.n; ++e) {
        const i64 i = cfg_dof[e];
        const double q = qpos[i];
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
    Box box;
    box.bad = core::merge_boxes(CVecRef(hard_lb), CVecRef(hard_ub), CVecRef(pos_lb),
                                CVecRef(pos_ub), box.lb, box.ub);
    return box;
}

// Fill every task's rows of A, b, w; returns each level's LM term sum lm_damping
// |b_task|^2 (L).
inline Vec assemble_rows(const FusedArgs& a, i64 L) {
    const i64 n = a.qpos.n;
    Vec reg(static_cast<size_t>(L), 0.0);
    std::vector<double> local(static_cast<size_t>(6 * n));
    for (i64 t = 0; t < a.tasks.rows; ++t) {
        const i64 i = a.tasks(t, 1);
        const i64 row = a.tasks(t, 3);
        double mu;
        const double* cost;
        i64 size;
        if (a.tasks(t, 0) == 0) {
            const i64 kind = a.frames(i, 0), fid = a.frames(i, 1);
            const double* pos;
            const double* mat;
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
            const double* data = a.frame_data.row(i);
            cost = data + 7;
            CMatRef jac(a.jac + i * 6 * n, 6, n);
            mu = frame_rows(a.A, a.b.p, row, jac, pos, mat, data, cost, data[13], data[14],
                            local.data());
            size = 6;
        } else {
            const double* data = a.posture_data.row(i);
            const i64 nq = a.posture_data.cols - n - 2;
            cost = data + nq;
            mu = posture_rows(a.A, a.b.p, row, a.qpos, data, cost, data[nq + n], data[nq + n + 1]);
            size = n;
        }
        for (i64 r = 0; r < size; ++r) a.w[row + r] = cost[r];
        reg[a.tasks(t, 2)] += mu;
    }
    return reg;
}

struct RowsResult {
    i64 code = OK;
    Vec reg;  // (L,)
    Box box;
};

// The hierarchy's rows and limits without solving it: fills A, b, w; code OK, NOT_FINITE
// (a row or regularisation) or CONFLICT (velocity-like limits of a dof).
inline RowsResult fused_rows(const FusedArgs& a) {
    const i64 n = a.qpos.n;
    const i64 L = a.starts.n - 1;
    RowsResult res;
    res.reg = assemble_rows(a, L);
    for (i64 k = 0; k < L; ++k) res.reg[k] = a.settings[DAMPING] + res.reg[k];
    const double* cfg = a.cfg_data.p;
    res.box = boxes(a.qpos, a.settings[DT], a.cfg_dof, cfg, cfg + 1, cfg + 2, a.cfg_data.stride,
                    a.vel_dof, a.vel_limit, n);
    double square = 0.0;
    double total = 0.0;
    for (i64 r = 0; r < a.b.n; ++r) {
        square += a.b[r] * a.b[r];
        for (i64 j = 0; j < n; ++j) total += a.A(r, j);
    }
    double reg_sum = 0.0;
    for (i64 k = 0; k < L; ++k) reg_sum += res.reg[k];
    if (!(std::isfinite(square) && std::isfinite(total) && std::isfinite(reg_sum))) {
        res.code = NOT_FINITE;
    } else if (res.box.bad >= 0) {
        res.code = CONFLICT;
    }
    return res;
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
inline StepResult fused_step(const FusedArgs& a, i64 max_iter, MatRefT<const i8> warm,
                             bool canonical) {
    const i64 n = a.qpos.n;
    const i64 L = a.starts.n - 1;
    RowsResult rows = fused_rows(a);
    StepResult out;
    out.code = rows.code;
    out.info.assign(static_cast<size_t>(9 * L), 0.0);
    if (rows.code != OK) {
        out.d.assign(static_cast<size_t>(n), 0.0);
        out.v_is_d = true;
        out.active.assign(static_cast<size_t>(L * n), 0);
        out.active_cols = n;
        return out;
    }
    const double dt = a.settings[DT];
    core::CascadeResult c = core::solve_cascade(
        CMatRef(a.A), CVecRef(a.b), CVecRef(a.w), a.starts, CVecRef(rows.reg),
        CVecRef(rows.box.lb), CVecRef(rows.box.ub), CMatRef(nullptr, 0, n), CVecRef(nullptr, 0),
        a.settings[THRESHOLD], a.settings[MAX_DAMPING], a.settings[ERROR_SCALE],
        a.settings[RANK_TOL], max_iter, a.settings[TOL], warm, canonical);
    out.d = std::move(c.dq);
    out.active = std::move(c.active);
    out.active_cols = L > 0 ? static_cast<i64>(out.active.size()) / L : n;
    double res_sum = 0.0;
    for (double r : c.residuals) res_sum += r;
    bool finite = std::isfinite(res_sum);
    for (i64 k = 0; k < L; ++k) {
        if (c.status[k] == core::MAX_ITER || c.status[k] == core::NUMERICAL) {
            out.code = UNSETTLED;
            out.v_is_d = true;
            return out;
        }
        out.info[0 * L + k] = c.residuals[k];
        out.info[1 * L + k] = c.sigma[k];
        out.info[2 * L + k] = c.lam2[k];
        out.info[3 * L + k] = static_cast<double>(c.status[k]);
        out.info[4 * L + k] = static_cast<double>(c.iterations[k]);
        for (i64 j = 0; j < 4; ++j) out.info[(5 + j) * L + k] = c.certificate[4 * k + j];
    }
    out.v.assign(static_cast<size_t>(n), 0.0);
    for (i64 i = 0; i < n; ++i) {
        out.v[i] = out.d[i] / dt;
        finite = finite && std::isfinite(out.d[i] * out.d[i]) && std::isfinite(out.v[i]);
    }
    if (!finite) {
        out.code = NOT_FINITE;
        out.v_is_d = true;
    }
    return out;
}

}  // namespace qpik::diffik

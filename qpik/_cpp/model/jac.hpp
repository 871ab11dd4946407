// MuJoCo's mj_jac along a dof chain, from the MjData's cdof (nv, 6) (mj_comPos): per dof da
// of the chain, the rotation rows cdof[da][0:3] and the translation rows cdof[da][3:6] +
// cdof[da][0:3] x offset, offset = point - subtree_com[root] (the body's root). The chain is
// the dofs that move the body, as mj_jac visits them (qpik.model.frames.frame_chains). The
// same operations in the same order as mj_jac: bitwise its answer (tested).
#pragma once

#include "../common.hpp"

namespace qpik::model {

// The chain dofs[0:count]'s columns of the point's Jacobian: translation rows into jp
// (3, n, row-major), rotation rows into jr (3, n) where jr is not null. The other columns
// are left as they are (zero them first for the whole Jacobian).
inline void chain_point_jacobian(const double* cdof, i64 n, const i64* dofs, i64 count, const double* point,
                                 const double* root_com, double* jp, double* jr) {
    double offset[3];
    for (int k = 0; k < 3; ++k) offset[k] = point[k] - root_com[k];
    for (i64 e = 0; e < count; ++e) {
        const i64 da = dofs[e];
        const double* cd = cdof + 6 * da;
        if (jr != nullptr) {
            jr[da] = cd[0];
            jr[da + n] = cd[1];
            jr[da + 2 * n] = cd[2];
        }
        double tmp[3];
        tmp[0] = cd[1] * offset[2] - cd[2] * offset[1];
        tmp[1] = cd[2] * offset[0] - cd[0] * offset[2];
        tmp[2] = cd[0] * offset[1] - cd[1] * offset[0];
        jp[da] = cd[3] + tmp[0];
        jp[da + n] = cd[4] + tmp[1];
        jp[da + 2 * n] = cd[5] + tmp[2];
    }
}

namespace detail {

// w = u x v.
inline void hessian_cross(const double* u, const double* v, double* w) {
    w[0] = u[1] * v[2] - u[2] * v[1];
    w[1] = u[2] * v[0] - u[0] * v[2];
    w[2] = u[0] * v[1] - u[1] * v[0];
}

// Column a of J = [J_v; J_w] and of W (6, n): jv, jw, wv, ww (3 each).
inline void hessian_columns(const double* jac, const double* W, i64 n, i64 a, double* jv, double* jw, double* wv,
                            double* ww) {
    for (int r = 0; r < 3; ++r) {
        jv[r] = jac[r * n + a];
        jw[r] = jac[(3 + r) * n + a];
        wv[r] = W[r * n + a];
        ww[r] = W[(3 + r) * n + a];
    }
}

}  // namespace detail

// <dJ/dq_a, W> for every dof a: J = [J_v; J_w] (6, n, row-major) a frame's Jacobian at its
// point, W (6, n) weights, on a chain of hinges and slides (chain[0:m]: its dofs, root first,
// each one's axis and anchor moved by the ones before it; a slide's J_w is 0). The columns'
// derivatives in closed form (the kinematic Hessian; Haviland and Corke 2023, part I):
// dJ_w,b/dq_a = J_w,a x J_w,b where a comes before b (else 0), dJ_v,b/dq_a = J_w,min(a,b) x
// J_v,max(a,b): what mj_jacDot gives at the joint velocity e_a. Each term <dJ_b/dq_a, W_b> is
// a triple product, so out[a] = J_w,a . sum_{b > a} (J_w,b x W_w,b) + J_w,a . sum_{b >= a}
// (J_v,b x W_v,b) + J_v,a . sum_{b < a} (W_v,b x J_w,b); out's other entries 0.
// The chain is read as chain[0], chain[stride], ..., chain[(m - 1) stride] (stride -1 from
// its last entry: a leaf-first list read root first).
inline void hessian_weights(const double* jac, const double* W, i64 n, const i64* chain, i64 m, double* out,
                            i64 stride = 1) {
    for (i64 k = 0; k < n; ++k) out[k] = 0.0;
    auto at = [n](const double* M, int r, i64 c) { return M[r * n + c]; };
    const auto cross = detail::hessian_cross;
    double after[3] = {0.0, 0.0, 0.0};  // sum over b > a of J_w,b x W_w,b (a from the last)
    double on[3] = {0.0, 0.0, 0.0};     // sum over b >= a of J_v,b x W_v,b
    for (i64 e = m - 1; e >= 0; --e) {
        const i64 a = chain[e * stride];
        double jw[3], jv[3], ww[3], wv[3], t[3];
        detail::hessian_columns(jac, W, n, a, jv, jw, wv, ww);
        cross(jv, wv, t);
        for (int r = 0; r < 3; ++r) on[r] += t[r];
        out[a] = jw[0] * (after[0] + on[0]) + jw[1] * (after[1] + on[1]) + jw[2] * (after[2] + on[2]);
        cross(jw, ww, t);
        for (int r = 0; r < 3; ++r) after[r] += t[r];
    }
    double before[3] = {0.0, 0.0, 0.0};  // sum over b < a of W_v,b x J_w,b
    for (i64 e = 0; e < m; ++e) {
        const i64 a = chain[e * stride];
        double jw[3], wv[3], t[3];
        for (int r = 0; r < 3; ++r) {
            jw[r] = at(jac, 3 + r, a);
            wv[r] = at(W, r, a);
        }
        out[a] += at(jac, 0, a) * before[0] + at(jac, 1, a) * before[1] + at(jac, 2, a) * before[2];
        cross(wv, jw, t);
        for (int r = 0; r < 3; ++r) before[r] += t[r];
    }
}

// hessian_weights on any chain of MuJoCo joints (free and ball joints too): what mj_jacDot
// gives at each joint velocity e_a (its cdof_dot: mj_comVel's for hinges and slides, the
// body's whole velocity crossed with cdof for a ball's or a free joint's rotational dofs,
// zero for a free joint's translational ones; and the point's own velocity). Column b's
// axis moves with dof a exactly where a < threshold[b] (threshold (nv,) by dof: b itself
// for a hinge or slide, its body's last dof + 1 for a ball's or a free joint's rotational
// dof, 0 for a free joint's translational dof: qpik.model.gradients.motion_chain). Then
// dJ_w,b/dq_a = J_w,a x J_w,b there (else 0) and dJ_v,b/dq_a = J_w,a x J_v,b there, else
// J_w,b x J_v,a, so out[a] = J_w,a . sum_{b: a < t_b} (J_w,b x W_w,b + J_v,b x W_v,b) +
// J_v,a . sum_{b: a >= t_b} (W_v,b x J_w,b); out's other entries 0. O(m^2) in the chain's
// length; the chain read as in hessian_weights.
inline void hessian_weights_any(const double* jac, const double* W, i64 n, const i64* chain, i64 m, double* out,
                                i64 stride, const i64* threshold, double* scratch /* 6 m */) {
    for (i64 k = 0; k < n; ++k) out[k] = 0.0;
    auto at = [n](const double* M, int r, i64 c) { return M[r * n + c]; };
    const auto cross = detail::hessian_cross;
    double* P = scratch;      // (m, 3): J_w,b x W_w,b + J_v,b x W_v,b
    double* Q = scratch + 3 * m;  // (m, 3): W_v,b x J_w,b
    for (i64 e = 0; e < m; ++e) {
        const i64 b = chain[e * stride];
        double jw[3], jv[3], ww[3], wv[3], t1[3], t2[3];
        detail::hessian_columns(jac, W, n, b, jv, jw, wv, ww);
        cross(jw, ww, t1);
        cross(jv, wv, t2);
        for (int r = 0; r < 3; ++r) P[3 * e + r] = t1[r] + t2[r];
        cross(wv, jw, Q + 3 * e);
    }
    for (i64 ea = 0; ea < m; ++ea) {
        const i64 a = chain[ea * stride];
        double moved[3] = {0.0, 0.0, 0.0}, still[3] = {0.0, 0.0, 0.0};
        for (i64 e = 0; e < m; ++e) {
            const i64 b = chain[e * stride];
            double* sum = a < threshold[b] ? moved : still;
            const double* term = a < threshold[b] ? P + 3 * e : Q + 3 * e;
            for (int r = 0; r < 3; ++r) sum[r] += term[r];
        }
        out[a] = (at(jac, 3, a) * moved[0] + at(jac, 4, a) * moved[1] + at(jac, 5, a) * moved[2]) +
                 (at(jac, 0, a) * still[0] + at(jac, 1, a) * still[1] + at(jac, 2, a) * still[2]);
    }
}

}  // namespace qpik::model

// SE(3) routines of mink's compiled Lie-group module (mink/lie/_lie_ops_c.c), ported
// operation for operation: the same floating-point operations in the same order, so the
// answers equal mink's to round-off. The SO(3) parts (log, inverse left Jacobian) are
// those of so3.hpp.
//
// Poses are wxyz_xyz (7): a unit quaternion (w, x, y, z) then a translation [m]. Tangents
// are [v; omega] (6) [m, rad]. 3x3 matrices are row-major (9), as MuJoCo's xmat; the 6x6
// jlog is row-major (36). Every function writes into `out`; nothing is allocated. The
// caller guarantees the sizes (the bindings check them).
#pragma once

#include <cmath>

#include "../common.hpp"
#include "../detmath.hpp"
#include "so3.hpp"

namespace qpik::model {

namespace se3_detail {

using so3_detail::dot3;

inline void quat_mul(double* out, const double* a, const double* b) {
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

// out = q v q^-1 (v (3), q (w, x, y, z)).
inline void quat_rotate(double* out, const double* v, const double* q) {
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    const double tx = 2.0 * (y * v[2] - z * v[1]);
    const double ty = 2.0 * (z * v[0] - x * v[2]);
    const double tz = 2.0 * (x * v[1] - y * v[0]);
    out[0] = v[0] + w * tx + (y * tz - z * ty);
    out[1] = v[1] + w * ty + (z * tx - x * tz);
    out[2] = v[2] + w * tz + (x * ty - y * tx);
}

inline void skew(double* out, const double* v) {
    out[0] = 0.0;
    out[1] = -v[2];
    out[2] = v[1];
    out[3] = v[2];
    out[4] = 0.0;
    out[5] = -v[0];
    out[6] = -v[1];
    out[7] = v[0];
    out[8] = 0.0;
}

// Written out entry by entry (the loops' operations in their order: the same bits, about
// half the instructions of the rolled loops at -O2).
inline void mat33_mul(double* C, const double* A, const double* B) {
#define QPIK_MAT33_ENTRY(i, j) \
    C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j]
    QPIK_MAT33_ENTRY(0, 0);
    QPIK_MAT33_ENTRY(0, 1);
    QPIK_MAT33_ENTRY(0, 2);
    QPIK_MAT33_ENTRY(1, 0);
    QPIK_MAT33_ENTRY(1, 1);
    QPIK_MAT33_ENTRY(1, 2);
    QPIK_MAT33_ENTRY(2, 0);
    QPIK_MAT33_ENTRY(2, 1);
    QPIK_MAT33_ENTRY(2, 2);
#undef QPIK_MAT33_ENTRY
}

inline void mat33_transpose(double* out, const double* m) {
    out[0] = m[0];
    out[1] = m[3];
    out[2] = m[6];
    out[3] = m[1];
    out[4] = m[4];
    out[5] = m[7];
    out[6] = m[2];
    out[7] = m[5];
    out[8] = m[8];
}

}  // namespace se3_detail

// A MuJoCo frame (xmat row-major 9, xpos 3) as wxyz_xyz (Shepperd's method).
inline void xmat_xpos_to_wxyz_xyz(double* out, const double* R, const double* xpos) {
    const double tr = R[0] + R[4] + R[8];
    if (tr > 0.0) {
        const double s = std::sqrt(tr + 1.0) * 2.0;
        out[0] = 0.25 * s;
        out[1] = (R[7] - R[5]) / s;
        out[2] = (R[2] - R[6]) / s;
        out[3] = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        const double s = std::sqrt(1.0 + R[0] - R[4] - R[8]) * 2.0;
        out[0] = (R[7] - R[5]) / s;
        out[1] = 0.25 * s;
        out[2] = (R[1] + R[3]) / s;
        out[3] = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        const double s = std::sqrt(1.0 + R[4] - R[0] - R[8]) * 2.0;
        out[0] = (R[2] - R[6]) / s;
        out[1] = (R[1] + R[3]) / s;
        out[2] = 0.25 * s;
        out[3] = (R[5] + R[7]) / s;
    } else {
        const double s = std::sqrt(1.0 + R[8] - R[0] - R[4]) * 2.0;
        out[0] = (R[3] - R[1]) / s;
        out[1] = (R[2] + R[6]) / s;
        out[2] = (R[5] + R[7]) / s;
        out[3] = 0.25 * s;
    }
    const double n = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
    if (n > 0.0) {
        const double inv = 1.0 / n;
        for (int i = 0; i < 4; ++i) out[i] *= inv;
    }
    out[4] = xpos[0];
    out[5] = xpos[1];
    out[6] = xpos[2];
}

// log(T) as [v; omega].
inline void se3_log(double* tangent, const double* T) {
    using namespace se3_detail;
    double omega[3];
    so3_log(omega, T);
    const double theta = std::sqrt(dot3(omega, omega));
    const double t2 = theta * theta;
    double skw[9], skw2[9], vinv[9];
    skew(skw, omega);
    mat33_mul(skw2, skw, skw);
    if (t2 < kLieEps) {
#pragma GCC unroll 9
        for (int i = 0; i < 9; ++i) vinv[i] = -0.5 * skw[i] + skw2[i] / 12.0;
    } else {
        const double half = 0.5 * theta;
        double sh, ch;
        dm::sincos(half, sh, ch);
        const double coeff = (1.0 - 0.5 * theta * ch / sh) / t2;
#pragma GCC unroll 9
        for (int i = 0; i < 9; ++i) vinv[i] = -0.5 * skw[i] + coeff * skw2[i];
    }
    vinv[0] += 1.0;
    vinv[4] += 1.0;
    vinv[8] += 1.0;
    const double t0 = T[4], t1 = T[5], t2_ = T[6];
    tangent[0] = vinv[0] * t0 + vinv[1] * t1 + vinv[2] * t2_;
    tangent[1] = vinv[3] * t0 + vinv[4] * t1 + vinv[5] * t2_;
    tangent[2] = vinv[6] * t0 + vinv[7] * t1 + vinv[8] * t2_;
    tangent[3] = omega[0];
    tangent[4] = omega[1];
    tangent[5] = omega[2];
}

// out = a^-1 b.
inline void se3_inverse_multiply(double* out, const double* a, const double* b) {
    using namespace se3_detail;
    const double inv_q[4] = {a[0], -a[1], -a[2], -a[3]};
    const double neg_t[3] = {-a[4], -a[5], -a[6]};
    double inv_t[3];
    quat_rotate(inv_t, neg_t, inv_q);
    // As the reference: the quaternion is written before b's translation is read.
    quat_mul(out, inv_q, b);
    double rotated[3];
    quat_rotate(rotated, b + 4, inv_q);
    out[4] = rotated[0] + inv_t[0];
    out[5] = rotated[1] + inv_t[1];
    out[6] = rotated[2] + inv_t[2];
}

// out = a^-1 (mink's _se3_inverse).
inline void se3_inverse(double* out, const double* a) {
    using namespace se3_detail;
    out[0] = a[0];
    out[1] = -a[1];
    out[2] = -a[2];
    out[3] = -a[3];
    const double neg_t[3] = {-a[4], -a[5], -a[6]};
    quat_rotate(out + 4, neg_t, out);
}

// The rotation matrix (row-major 9) of a unit quaternion wxyz (mink's quat_to_mat33).
inline void quat_to_mat33(double* R, const double* q) {
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    const double x2 = x * x, y2 = y * y, z2 = z * z;
    const double xy = x * y, xz = x * z, yz = y * z;
    const double wx = w * x, wy = w * y, wz = w * z;
    R[0] = 1.0 - 2.0 * (y2 + z2);
    R[1] = 2.0 * (xy - wz);
    R[2] = 2.0 * (xz + wy);
    R[3] = 2.0 * (xy + wz);
    R[4] = 1.0 - 2.0 * (x2 + z2);
    R[5] = 2.0 * (yz - wx);
    R[6] = 2.0 * (xz - wy);
    R[7] = 2.0 * (yz + wx);
    R[8] = 1.0 - 2.0 * (x2 + y2);
}

// The adjoint of T (row-major 6x6, 36) on [v; omega]: [[R, skew(t) R], [0, R]] (mink's
// _se3_adjoint).
inline void se3_adjoint(double* adj, const double* T) {
    using namespace se3_detail;
    double R[9], skw[9], skR[9];
    quat_to_mat33(R, T);
    skew(skw, T + 4);
    mat33_mul(skR, skw, R);
    for (int i = 0; i < 36; ++i) adj[i] = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            adj[6 * i + j] = R[3 * i + j];
            adj[6 * i + (j + 3)] = skR[3 * i + j];
            adj[6 * (i + 3) + (j + 3)] = R[3 * i + j];
        }
}

// a (-) b = log(b^-1 a).
inline void se3_rminus(double* tangent, const double* a, const double* b) {
    double temp[7];
    se3_inverse_multiply(temp, b, a);
    se3_log(tangent, temp);
}

namespace se3_detail {

// The Q block of the SE(3) left Jacobian (Sola et al., eq. 180) at c (6).
// get_q with theta = |c[3:6]| and, where theta^2 >= kLieEps, st = sin(theta), ct =
// cos(theta) already computed (as get_q computes them: the same bits).
inline void get_q_at(double* Q, const double* c, double theta, double st, double ct) {
    const double* v = c;
    const double* w = c + 3;
    const double t2 = theta * theta;
    const double A = 0.5;
    double B, C, D;
    if (t2 < kLieEps) {
        B = (1.0 / 6.0) + (1.0 / 120.0) * t2;
        C = -(1.0 / 24.0) + (1.0 / 720.0) * t2;
        D = -(1.0 / 60.0);
    } else {
        const double t4 = t2 * t2;
        B = (theta - st) / (t2 * theta);
        C = (1.0 - 0.5 * t2 - ct) / t4;
        D = (2.0 * theta - 3.0 * st + theta * ct) / (2.0 * t4 * theta);
    }
    double V[9], W[9], VW[9], WV[9], WVW[9], VWW[9], VWW_T[9], WVWW[9], WWVW[9];
    skew(V, v);
    skew(W, w);
    mat33_mul(VW, V, W);
    mat33_transpose(WV, VW);
    mat33_mul(WVW, WV, W);
    mat33_mul(VWW, VW, W);
    mat33_transpose(VWW_T, VWW);
    mat33_mul(WVWW, WVW, W);
    mat33_mul(WWVW, W, WVW);
#pragma GCC unroll 9
    for (int i = 0; i < 9; ++i) {
        Q[i] = A * V[i] + B * (WV[i] + VW[i] + WVW[i]) - C * (VWW[i] - VWW_T[i] - 3.0 * WVW[i]) +
               D * (WVWW[i] + WWVW[i]);
    }
}

inline void get_q(double* Q, const double* c) {
    const double* w = c + 3;
    const double theta = std::sqrt(dot3(w, w));
    const double t2 = theta * theta;
    double st = 0.0, ct = 1.0;
    if (!(t2 < kLieEps)) {
        dm::sincos(theta, st, ct);
    }
    get_q_at(Q, c, theta, st, ct);
}

}  // namespace se3_detail

// jlog(T): the right Jacobian inverse at log(T), row-major 6x6 (36).
inline void se3_jlog(double* jlog, const double* T) {
    using namespace se3_detail;
    double tangent[6];
    se3_log(tangent, T);
    double neg[6];
    for (int i = 0; i < 6; ++i) neg[i] = -tangent[i];
    for (int i = 0; i < 36; ++i) jlog[i] = 0.0;
    if (dot3(neg + 3, neg + 3) < kLieEps) {
        for (int i = 0; i < 6; ++i) jlog[6 * i + i] = 1.0;
        return;
    }
    // get_q and so3_ljacinv at the same theta = |neg[3:6]| (each computes it so): one sin
    // and cos for both.
    double Q[9], lji[9];
    const double theta = std::sqrt(dot3(neg + 3, neg + 3));
    double st = 0.0, ct = 1.0;
    if (!(theta * theta < kLieEps)) {
        dm::sincos(theta, st, ct);
    }
    get_q_at(Q, neg, theta, st, ct);
    so3_ljacinv_at(lji, neg + 3, theta, st, ct);
#pragma GCC unroll 3
    for (int i = 0; i < 3; ++i)
#pragma GCC unroll 3
        for (int j = 0; j < 3; ++j) {
            jlog[6 * i + j] = lji[3 * i + j];
            jlog[6 * (3 + i) + 3 + j] = lji[3 * i + j];
        }
    double QJ[9], JQJ[9];
    mat33_mul(QJ, Q, lji);
    mat33_mul(JQJ, lji, QJ);
#pragma GCC unroll 3
    for (int i = 0; i < 3; ++i)
#pragma GCC unroll 3
        for (int j = 0; j < 3; ++j) jlog[6 * i + 3 + j] = -JQJ[3 * i + j];
}

}  // namespace qpik::model

// SO(3): the log of a rotation matrix (rotation_log) and of a unit quaternion (so3_log,
// mink's), the inverse left Jacobian (so3_ljacinv, mink's), and the checks of a rotation
// target. se3.hpp builds SE(3) on these.
#pragma once

#include <cmath>

#include "../common.hpp"
#include "../detmath.hpp"

namespace qpik::model {

constexpr double kLieEps = 1e-10;

namespace so3_detail {

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace so3_detail

// Rotation vector (axis * angle [rad]) of the row-major 3x3 R into out; returns the angle.
// The log of SO(3) on matrices.
// Accurate near 0 (atan2 of the skew part) and near pi (axis from the symmetric part).
inline double rotation_log(const double* R, double* out) {
    auto r = [R](int i, int j) { return R[3 * i + j]; };
    double v0 = 0.5 * (r(2, 1) - r(1, 2));
    double v1 = 0.5 * (r(0, 2) - r(2, 0));
    double v2 = 0.5 * (r(1, 0) - r(0, 1));
    double s = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
    double c = 0.5 * (r(0, 0) + r(1, 1) + r(2, 2) - 1.0);
    double theta = dm::atan2(s, c);
    if (c > -0.9) {
        if (s < 1e-300) {
            out[0] = 0.0;
            out[1] = 0.0;
            out[2] = 0.0;
            return 0.0;
        }
        double k = theta / s;
        out[0] = k * v0;
        out[1] = k * v1;
        out[2] = k * v2;
        return theta;
    }
    // Near pi: R + R^T = 2 c I + 2 (1 - c) u u^T.
    int best = 0;
    for (int i = 1; i < 3; ++i)
        if (r(i, i) > r(best, best)) best = i;
    double u[3];
    for (int i = 0; i < 3; ++i) u[i] = 0.5 * (r(i, best) + r(best, i));
    u[best] -= c;
    double norm = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int i = 0; i < 3; ++i) u[i] /= norm;
    if (u[0] * v0 + u[1] * v1 + u[2] * v2 < 0.0)
        for (int i = 0; i < 3; ++i) u[i] = -u[i];
    for (int i = 0; i < 3; ++i) out[i] = theta * u[i];
    return theta;
}

// max |R R^T - I| of a 3x3 matrix, or inf when an entry is not finite or det R <= 0.
inline double rotation_defect(const double* R) {
    auto r = [R](int i, int j) { return R[3 * i + j]; };
    for (int i = 0; i < 9; ++i)
        if (!std::isfinite(R[i])) return kInf;
    double det = r(0, 0) * (r(1, 1) * r(2, 2) - r(1, 2) * r(2, 1)) -
                 r(0, 1) * (r(1, 0) * r(2, 2) - r(1, 2) * r(2, 0)) +
                 r(0, 2) * (r(1, 0) * r(2, 1) - r(1, 1) * r(2, 0));
    if (!(det > 0.0)) return kInf;
    double worst = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double s = r(i, 0) * r(j, 0) + r(i, 1) * r(j, 1) + r(i, 2) * r(j, 2);
            if (i == j) s -= 1.0;
            double a = std::fabs(s);
            if (a > worst) worst = a;  // Python's max(worst, a)
        }
    }
    return worst;
}

// 0 for a valid target; 1: the position is not finite; 2: the rotation is not finite;
// 3: the rotation is not a rotation (|R R^T - I| > 1e-6 or det R <= 0).
inline i64 target_defect(const double* position, const double* rotation, bool has_rot) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(position[i])) return 1;
    if (has_rot) {
        double defect = rotation_defect(rotation);
        if (!(defect <= 1e-6)) {
            for (int i = 0; i < 9; ++i)
                if (!std::isfinite(rotation[i])) return 2;
            return 3;
        }
    }
    return 0;
}

// Rotation vector [rad] of a unit quaternion (the shorter way round); reads wxyz[0:4].
// mink's _so3_log: the log of SO(3) on quaternions (rotation_log is the one on matrices).
inline void so3_log(double* omega, const double* wxyz) {
    double w = wxyz[0], x = wxyz[1], y = wxyz[2], z = wxyz[3];
    if (w < 0.0) {
        w = -w;
        x = -x;
        y = -y;
        z = -z;
    }
    const double norm = std::sqrt(x * x + y * y + z * z);
    if (norm > 0.0) {
        const double inv = 1.0 / norm;
        x = x * inv;
        y = y * inv;
        z = z * inv;
    }
    if (norm < kLieEps) {
        omega[0] = 0.0;
        omega[1] = 0.0;
        omega[2] = 0.0;
        return;
    }
    const double angle = 2.0 * dm::atan2(norm, w);
    omega[0] = angle * x;
    omega[1] = angle * y;
    omega[2] = angle * z;
}

// Inverse left Jacobian of SO(3) at rotation vector omega into out (row-major 3x3):
// d log(R) = Jl^-1 omega' for a world perturbation dR = [omega'] R: mink's _so3_ljacinv,
// used by jlog of SE(3) (the frame tasks) and the IGM. Its series is taken below
// theta^2 = kLieEps (mink: theta < kLieEps), where jlog never calls it, so jlog keeps mink's
// answers bitwise: mink's closed form divides by 1 - cos(theta), which rounds to 0 below
// theta ~ 1e-8 (a NaN) and keeps ~|log10 theta^2| - 6 digits above 1e-5.
// so3_ljacinv with theta = |omega| and, where theta^2 >= kLieEps, st = sin(theta), ct =
// cos(theta) already computed (as so3_ljacinv computes them: the same bits).
inline void so3_ljacinv_at(double* out, const double* omega, double theta, double st, double ct) {
    using so3_detail::dot3;
    const double t2 = theta * theta;
    double beta;
    if (t2 < kLieEps) {
        beta = (1.0 / 12.0) * (1.0 + t2 / 60.0 * (1.0 + t2 / 42.0 * (1.0 + t2 / 40.0)));
    } else {
        beta = (1.0 / t2) * (1.0 - (theta * st / (2.0 * (1.0 - ct))));
    }
    const double inner = dot3(omega, omega);
#pragma GCC unroll 3
    for (int i = 0; i < 3; ++i)
#pragma GCC unroll 3
        for (int j = 0; j < 3; ++j)
            out[3 * i + j] = beta * (omega[i] * omega[j] - (i == j ? inner : 0.0));
    const double a0 = -0.5 * omega[0], a1 = -0.5 * omega[1], a2 = -0.5 * omega[2];
    out[1] += -a2;
    out[2] += a1;
    out[3] += a2;
    out[5] += -a0;
    out[6] += -a1;
    out[7] += a0;
    out[0] += 1.0;
    out[4] += 1.0;
    out[8] += 1.0;
}

inline void so3_ljacinv(double* out, const double* omega) {
    using so3_detail::dot3;
    const double theta = std::sqrt(dot3(omega, omega));
    const double t2 = theta * theta;
    double st = 0.0, ct = 1.0;
    if (!(t2 < kLieEps)) {
        dm::sincos(theta, st, ct);
    }
    so3_ljacinv_at(out, omega, theta, st, ct);
}

}  // namespace qpik::model

// Rotations of the model layer: log of SO(3), the inverse left Jacobian and the checks
// of a rotation target (ported from qpik/model/_kernels.py, same operation order).
#pragma once

#include "../common.hpp"

namespace qpik::model {

// Rotation vector (axis * angle [rad]) of the row-major 3x3 R into out; returns the angle.
// Accurate near 0 (atan2 of the skew part) and near pi (axis from the symmetric part).
inline double rotation_log(const double* R, double* out) {
    auto r = [R](int i, int j) { return R[3 * i + j]; };
    double v0 = 0.5 * (r(2, 1) - r(1, 2));
    double v1 = 0.5 * (r(0, 2) - r(2, 0));
    double v2 = 0.5 * (r(1, 0) - r(0, 1));
    double s = std::sqrt(v0 * v0 + v1 * v1 + v2 * v2);
    double c = 0.5 * (r(0, 0) + r(1, 1) + r(2, 2) - 1.0);
    double theta = std::atan2(s, c);
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

// Inverse left Jacobian of SO(3) at rotation vector phi into out (3x3 row-major):
// d log(R) = Jl^-1 omega for a world perturbation dR = [omega] R.
inline void left_jacobian_inverse(const double* phi, double* out) {
    double theta = std::sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]);
    double S[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    S[0][1] = -phi[2];
    S[0][2] = phi[1];
    S[1][0] = phi[2];
    S[1][2] = -phi[0];
    S[2][0] = -phi[1];
    S[2][1] = phi[0];
    double k;
    if (theta < 1e-6)
        k = 1.0 / 12.0;
    else
        k = 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double s2 = S[i][0] * S[0][j] + S[i][1] * S[1][j] + S[i][2] * S[2][j];
            out[3 * i + j] = -0.5 * S[i][j] + k * s2;
        }
        out[3 * i + i] += 1.0;
    }
}

}  // namespace qpik::model

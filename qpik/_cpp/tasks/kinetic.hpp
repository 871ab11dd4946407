// mink's KineticEnergyRegularizationTask (and qpik's): the objective 1/2 dq^T H dq with
// H = (cost / dt^2) M(q), as least-squares rows A dq - b with A^T A = H, b = 0: A = L^T of
// the Cholesky factor H = L L^T. One routine for the compiled step (diffik/fused.hpp) and
// the task's rows on the QP path (qpik.diffik.rows), so the two agree bit for bit.
#pragma once

#include <algorithm>
#include <cmath>

#include "../common.hpp"

namespace qpik::tasks {

// Rows row:row+n of A (and b = 0) of H = scale M (M (n, n) symmetric, row-major); L (n * n)
// scratch. Zero rows where scale is 0 (H = 0). False where H is not positive definite with
// every pivot^2 above 1e-12 max(1, max diag H) (qpik.diffik.rows._cholesky_rows' test: the
// QP path then factors H by its eigendecomposition), or scale is not a finite number >= 0;
// the rows are then left unset.
inline bool kinetic_rows_into(MatRef A, double* b, i64 row, const double* M, i64 n, double scale, double* L) {
    if (!(std::isfinite(scale) && scale >= 0.0) || n == 0) return false;
    if (scale == 0.0) {
        for (i64 r = row; r < row + n; ++r) {
            for (i64 c = 0; c < n; ++c) A(r, c) = 0.0;
            b[r] = 0.0;
        }
        return true;
    }
    double top = 1.0;
    for (i64 i = 0; i < n; ++i) top = std::max(top, scale * M[i * n + i]);
    const double floor = 1e-12 * top;
    for (i64 i = 0; i < n; ++i) {  // H = L L^T, row by row (Cholesky-Banachiewicz)
        for (i64 j = 0; j <= i; ++j) {
            double s = scale * M[i * n + j];
            for (i64 k = 0; k < j; ++k) s -= L[i * n + k] * L[j * n + k];
            if (j < i) {
                L[i * n + j] = s / L[j * n + j];
            } else {
                if (!(s > floor)) return false;  // (pivot^2 = s; NaN fails too)
                L[i * n + i] = std::sqrt(s);
            }
        }
    }
    for (i64 r = 0; r < n; ++r) {  // A = L^T: row r is column r of L
        double* ar = A.row(row + r);
        for (i64 c = 0; c < r; ++c) ar[c] = 0.0;
        for (i64 c = r; c < n; ++c) ar[c] = L[c * n + r];
        b[row + r] = 0.0;
    }
    return true;
}

}  // namespace qpik::tasks

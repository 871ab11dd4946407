// Dense linear algebra of the core: Cholesky, triangular solves, small products, QR and
// the smallest singular value (ported from qpik/core/_kernels.py).
#pragma once

#include "../common.hpp"

namespace qpik::core {

// Cholesky factor of G[:n, :n] - shift I written into the lower triangle of L[:n, :n]
// (G unchanged); false as soon as a pivot is not positive (L then holds a partial factor).
inline bool cholesky_into(CMatRef G, i64 n, double shift, MatRef L) {
    for (i64 j = 0; j < n; ++j) {
        double s = G(j, j) - shift;
        for (i64 k = 0; k < j; ++k) s -= L(j, k) * L(j, k);
        if (!(s > 0.0)) return false;
        double d = std::sqrt(s);
        L(j, j) = d;
        for (i64 i = j + 1; i < n; ++i) {
            double t = G(i, j);
            for (i64 k = 0; k < j; ++k) t -= L(i, k) * L(j, k);
            L(i, j) = t / d;
        }
    }
    return true;
}

}  // namespace qpik::core

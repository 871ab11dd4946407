// The prioritised cascade (ported from qpik/core/_kernels.py: solve_cascade and the
// per-level helpers it calls). Owned by the core port; the signature of solve_cascade is
// the contract the diffik layer (diffik/fused.hpp) calls.
#pragma once

#include <stdexcept>

#include "../common.hpp"

namespace qpik::core {

// Status codes shared with qpik.core.hierarchy.LevelStatus (keep in sync).
enum Status : i64 { SOLVED = 0, MAX_ITER = 1, INFEASIBLE = 2, KEPT_PREVIOUS = 3, NUMERICAL = 4, NOT_REACHED = 5 };

// What solve_cascade returns (per level arrays have L entries).
struct CascadeResult {
    Vec dq;            // (n,)
    IVec status;       // (L,)
    Vec sigma;         // (L,)
    Vec lam2;          // (L,)
    IVec iterations;   // (L,)
    BVec active;       // (L, n + p) row-major: the final active sets
    Vec residuals;     // (L,) |A_k dq - b_k|
};

// All levels of a hierarchy in one call; see solve_cascade in qpik/core/_kernels.py for
// the arguments (A (M, n), b, w (M,), starts (L + 1,), reg (L,), lb, ub (n,), G (p, n),
// h (p,), warm (L, n + p) int8).
inline CascadeResult solve_cascade(CMatRef A, CVecRef b, CVecRef w, VecRefT<const i64> starts,
                                   CVecRef reg, CVecRef lb, CVecRef ub, CMatRef G, CVecRef h,
                                   double threshold, double max_damping, double error_scale,
                                   double rank_tol, i64 max_iter, double tol,
                                   MatRefT<const i8> warm, bool canonical) {
    (void)A; (void)b; (void)w; (void)starts; (void)reg; (void)lb; (void)ub; (void)G; (void)h;
    (void)threshold; (void)max_damping; (void)error_scale; (void)rank_tol; (void)max_iter;
    (void)tol; (void)warm; (void)canonical;
    throw std::logic_error("solve_cascade: not ported yet");
}

}  // namespace qpik::core

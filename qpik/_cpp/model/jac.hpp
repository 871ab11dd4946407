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

}  // namespace qpik::model

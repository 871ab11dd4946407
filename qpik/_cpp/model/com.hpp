// The Jacobian of a subtree's centre of mass from MuJoCo's com-based dof axes (named for
// Python in qpik/model/kernels.py; qpik/model/com.py builds its per-dof chain).
#pragma once

#include "../common.hpp"

namespace qpik::model {

// jac (3, nv) [m per unit of dq], world frame: d c_B / d q for the centre of mass c_B of body
// B's subtree, from mjData's cdof (nv, 6) ([omega; v] of each dof's motion, v of the point at
// subtree_com[root], root the dof's tree) and subtree_com (nbody, 3), in O(nv). A dof of body b
// moves the bodies of B's subtree that lie in b's subtree: b's whole subtree when b is in B's
// (mass m_b of m_B, centre subtree_com[b]), B's whole subtree when b is above B (centre
// subtree_com[B]), none otherwise. So its column is scale (v + omega x (c - subtree_com[root])),
// point[d] the body of c, scale[d] = m_b / m_B or 1 (0: a zero column, point[d] unread): the
// mass-weighted sum over the bodies that mj_jacSubtreeCom makes body by body (equal to
// round-off; the terms as mj_jac orders them: v + (omega x offset), then the scale).
inline void subtree_com_jacobian(const double* cdof, const double* subtree_com, i64 nv, const i64* point,
                                 const i64* root, const double* scale, double* jac) {
    double* jx = jac;
    double* jy = jac + nv;
    double* jz = jac + 2 * nv;
    for (i64 d = 0; d < nv; ++d) {
        const double s = scale[d];
        if (s == 0.0) {
            jx[d] = jy[d] = jz[d] = 0.0;
            continue;
        }
        const double* c = subtree_com + 3 * point[d];
        const double* o = subtree_com + 3 * root[d];
        const double off[3] = {c[0] - o[0], c[1] - o[1], c[2] - o[2]};
        const double* w = cdof + 6 * d;
        const double* v = w + 3;
        const double x = v[0] + (w[1] * off[2] - w[2] * off[1]);
        const double y = v[1] + (w[2] * off[0] - w[0] * off[2]);
        const double z = v[2] + (w[0] * off[1] - w[1] * off[0]);
        jx[d] = s == 1.0 ? x : s * x;
        jy[d] = s == 1.0 ? y : s * y;
        jz[d] = s == 1.0 ? z : s * z;
    }
}

}  // namespace qpik::model

// The joint-space inertia matrix M(q) by the composite rigid body algorithm, from the
// MjData's cinert (nbody, 10) and cdof (nv, 6) (mj_comPos), as MuJoCo's mj_crb computes it:
// each body's composite inertia crb = its cinert plus its children's (bodies from the last
// to the first), then per dof i, buf = crb[body(i)] * cdof_i (mju_mulInertVec) and
// M(i, j) = cdof_j . buf (mji_dot6's order) for j = i and each ancestor dof of i, plus the
// dof's armature on the diagonal; a "simple" dof (dof_simplenum) has its constant diagonal
// dof_M0 alone (its `fixed` entry). The same operations in the same order as mj_crb
// (bitwise MuJoCo's M, tested); the armature is the caller's (qpik.diffik.layout: a model
// whose actuators or tendons add armature is not computed here).
#pragma once

#include <cmath>
#include <vector>

#include "../common.hpp"

namespace qpik::model {

// The model's tree: per body its parent (body 0, the world, first), per dof its body, its
// parent dof (-1: none), armature and fixed diagonal (a simple dof's dof_M0, else NaN).
struct InertiaTree {
    i64 nbody = 0;
    i64 nv = 0;
    const i64* body_parent = nullptr;  // (nbody,)
    const i64* dof_body = nullptr;     // (nv,)
    const i64* dof_parent = nullptr;   // (nv,)
    const double* armature = nullptr;  // (nv,)
    const double* fixed = nullptr;     // (nv,)
};

// res = inert * vec, a cinert (10) times a motion (6) (MuJoCo's mju_mulInertVec).
inline void mul_inert_vec(double* res, const double* i, const double* v) {
    res[0] = i[0] * v[0] + i[3] * v[1] + i[4] * v[2] - i[8] * v[4] + i[7] * v[5];
    res[1] = i[3] * v[0] + i[1] * v[1] + i[5] * v[2] + i[8] * v[3] - i[6] * v[5];
    res[2] = i[4] * v[0] + i[5] * v[1] + i[2] * v[2] - i[7] * v[3] + i[6] * v[4];
    res[3] = i[8] * v[1] - i[7] * v[2] + i[9] * v[3];
    res[4] = i[6] * v[2] - i[8] * v[0] + i[9] * v[4];
    res[5] = i[7] * v[0] - i[6] * v[1] + i[9] * v[5];
}

// a . b of two 6-vectors in MuJoCo's order (mji_dot6).
inline double dot6(const double* a, const double* b) {
    return ((a[0] * b[0] + a[2] * b[2]) + (a[1] * b[1] + a[3] * b[3])) + (a[4] * b[4] + a[5] * b[5]);
}

// M (nv, nv, row-major, both triangles; the entries of dofs on different branches 0) from
// cinert and cdof; crb (nbody * 10) scratch.
inline void inertia_matrix(const InertiaTree& t, const double* cinert, const double* cdof, double* crb,
                           double* M) {
    const i64 nv = t.nv;
    for (i64 e = 0; e < 10 * t.nbody; ++e) crb[e] = cinert[e];
    for (i64 b = t.nbody - 1; b > 0; --b) {
        const i64 p = t.body_parent[b];
        if (p > 0)
            for (int e = 0; e < 10; ++e) crb[10 * p + e] += crb[10 * b + e];
    }
    for (i64 e = 0; e < nv * nv; ++e) M[e] = 0.0;
    for (i64 i = 0; i < nv; ++i) {
        if (!std::isnan(t.fixed[i])) {  // a simple dof: dof_M0
            M[i * nv + i] = t.fixed[i];
            continue;
        }
        double buf[6];
        mul_inert_vec(buf, crb + 10 * t.dof_body[i], cdof + 6 * i);
        M[i * nv + i] = t.armature[i];
        for (i64 j = i; j >= 0; j = t.dof_parent[j]) {
            const double v = M[i * nv + j] + dot6(cdof + 6 * j, buf);
            M[i * nv + j] = v;
            M[j * nv + i] = v;
        }
    }
}

}  // namespace qpik::model

// mink's EqualityConstraintTask (and qpik's): its rows are MuJoCo's equality constraint rows
// as mj_makeConstraint leaves them in the MjData (efc_type mjCNSTR_EQUALITY, efc_id the
// equality's id; efc_pos the residual, efc_J the Jacobian, dense or sparse), in efc order,
// for the equalities the task regulates; each weighted as mink weights any task: A = cost J,
// b = cost (-gain efc_pos), the LM term lm_damping |b|^2 (its squares summed in order), the
// cost of a row its equality's (mink's _cost by the equality's position in the task). One
// routine for the compiled step (diffik/fused.hpp) and the task's rows on the QP path
// (qpik.diffik.rows), so the two agree bit for bit.
#pragma once

#include <cstdint>

#include "../common.hpp"

namespace qpik::tasks {

constexpr std::int32_t kEqualityConstraint = 0;  // mjCNSTR_EQUALITY

// The MjData's constraint rows (views; sizes checked by the caller: J nefc * nv dense, or
// rownnz / rowadr (nefc) and colind (the length of J) with every column in [0, nv)).
struct EfcRows {
    i64 nefc = 0;
    i64 nv = 0;
    bool sparse = false;
    const double* J = nullptr;
    const double* pos = nullptr;
    const std::int32_t* type = nullptr;
    const std::int32_t* id = nullptr;
    const std::int32_t* rownnz = nullptr;
    const std::int32_t* rowadr = nullptr;
    const std::int32_t* colind = nullptr;
};

// Whether efc's arrays hold rows as equality_rows_into reads them, given their lengths
// (efc_J's `size`; efc_type's, efc_id's, and the sparse rownnz, rowadr and colind arrays'):
// efc_type and efc_id nefc entries; sparse, every row within efc_J and its columns in [0,
// nv); dense, efc_J at least nefc * nv long (MuJoCo may keep it longer: its first nefc * nv).
inline bool efc_rows_fit(const EfcRows& efc, i64 size, i64 ntype, i64 nid, i64 nrownnz, i64 nrowadr, i64 ncolind) {
    if (ntype != efc.nefc || nid != efc.nefc) return false;
    if (!efc.sparse) return size >= efc.nefc * efc.nv;
    if (nrownnz != efc.nefc || nrowadr != efc.nefc || ncolind != size) return false;
    for (i64 r = 0; r < efc.nefc; ++r)
        if (efc.rownnz[r] < 0 || efc.rowadr[r] < 0 || static_cast<i64>(efc.rowadr[r]) + efc.rownnz[r] > size)
            return false;
    for (i64 t = 0; t < size; ++t)
        if (efc.colind[t] < 0 || efc.colind[t] >= efc.nv) return false;
    return true;
}

// The task's rows into rows row:row+k of A and b, their costs into w (k returned; at most
// max_rows written, -1 where more rows belong to the task): position[e] is the task's
// position of equality e (neq entries, -1: not the task's), cost[position] its cost. mu
// receives lm |b|^2.
inline i64 equality_rows_into(MatRef A, double* b, double* w, i64 row, i64 max_rows, const EfcRows& efc,
                              const i64* position, i64 neq, const double* cost, double gain, double lm, double& mu) {
    const i64 n = efc.nv;
    i64 k = 0;
    double sq = 0.0;
    for (i64 r = 0; r < efc.nefc; ++r) {
        if (efc.type[r] != kEqualityConstraint) continue;
        const i64 e = efc.id[r];
        if (e < 0 || e >= neq || position[e] < 0) continue;
        if (k == max_rows) return -1;
        const double c = cost[position[e]];
        double* ar = A.row(row + k);
        if (efc.sparse) {
            for (i64 j = 0; j < n; ++j) ar[j] = c * 0.0;
            const i64 adr = efc.rowadr[r];
            for (i64 t = 0; t < efc.rownnz[r]; ++t) ar[efc.colind[adr + t]] = c * efc.J[adr + t];
        } else {
            const double* jr = efc.J + r * n;
            for (i64 j = 0; j < n; ++j) ar[j] = c * jr[j];
        }
        b[row + k] = c * (-gain * efc.pos[r]);
        w[row + k] = c;
        sq += b[row + k] * b[row + k];
        ++k;
    }
    mu = lm * sq;
    return k;
}

}  // namespace qpik::tasks

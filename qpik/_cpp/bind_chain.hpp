// The kinematic chain's tuple of NumPy arrays (qpik.model.KinematicChain.arrays) unpacked
// into a qpik::model::Chain, every array's dtype, shape and index range checked (a bad
// tuple raises ValueError instead of reading out of bounds); and ChainData, the same arrays
// copied once into a small owning struct (bound as qpik._engine.model.Chain), which the
// kernels take without unpacking eleven arrays per call.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "bind.hpp"
#include "model/chain.hpp"

namespace qpik::bind {

using I64In1 = In<i64, 1>;

struct ChainArgs {
    In2 body_pos;
    In3 body_rot;
    I64In1 jnt_start, jnt_type;
    In2 jnt_axis, jnt_pos;
    I64In1 jnt_qadr, jnt_dadr;
    In1 jnt_qpos0, frame_pos;
    In2 frame_rot;
    model::Chain chain;
};

template <class A>
inline void chain_item(const nb::tuple& t, size_t i, const char* what, A& out) {
    if (!nb::try_cast(t[i], out, true))
        throw BadArgument(std::string("chain[") + std::to_string(i) + "] (" + what +
                          ") must be an array of the chain's dtype (float64 or int64) and dimensions");
}

// Unpack and check the chain tuple: joint coordinates index arrays of nq entries and
// joint dofs arrays of nv entries.
inline ChainArgs unpack_chain(nb::handle obj, i64 nq, i64 nv) {
    require(nb::isinstance<nb::tuple>(obj), "chain must be a tuple of arrays (KinematicChain.arrays)");
    nb::tuple t = nb::borrow<nb::tuple>(obj);
    require(nb::len(t) >= 11, "chain must be a tuple of 11 arrays (KinematicChain.arrays)");
    ChainArgs a;
    chain_item(t, 0, "body_pos", a.body_pos);
    chain_item(t, 1, "body_rot", a.body_rot);
    chain_item(t, 2, "jnt_start", a.jnt_start);
    chain_item(t, 3, "jnt_type", a.jnt_type);
    chain_item(t, 4, "jnt_axis", a.jnt_axis);
    chain_item(t, 5, "jnt_pos", a.jnt_pos);
    chain_item(t, 6, "jnt_qadr", a.jnt_qadr);
    chain_item(t, 7, "jnt_dadr", a.jnt_dadr);
    chain_item(t, 8, "jnt_qpos0", a.jnt_qpos0);
    chain_item(t, 9, "frame_pos", a.frame_pos);
    chain_item(t, 10, "frame_rot", a.frame_rot);
    i64 nb_ = static_cast<i64>(a.body_pos.shape(0));
    i64 nj = static_cast<i64>(a.jnt_type.shape(0));
    require(a.body_pos.shape(1) == 3, "chain body_pos must be (nbody, 3)");
    require(static_cast<i64>(a.body_rot.shape(0)) == nb_ && a.body_rot.shape(1) == 3 && a.body_rot.shape(2) == 3,
            "chain body_rot must be (nbody, 3, 3)");
    require(static_cast<i64>(a.jnt_start.shape(0)) == nb_ + 1, "chain jnt_start must be (nbody + 1,)");
    const i64* start = a.jnt_start.data();
    require(start[0] >= 0, "chain jnt_start must start at >= 0");
    for (i64 b = 0; b < nb_; ++b) require(start[b] <= start[b + 1], "chain jnt_start must be nondecreasing");
    require(start[nb_] <= nj, "chain jnt_start must end at <= the number of joints");
    require(static_cast<i64>(a.jnt_axis.shape(0)) == nj && a.jnt_axis.shape(1) == 3, "chain jnt_axis must be (njnt, 3)");
    require(static_cast<i64>(a.jnt_pos.shape(0)) == nj && a.jnt_pos.shape(1) == 3, "chain jnt_pos must be (njnt, 3)");
    require(static_cast<i64>(a.jnt_qadr.shape(0)) == nj, "chain jnt_qadr must be (njnt,)");
    require(static_cast<i64>(a.jnt_dadr.shape(0)) == nj, "chain jnt_dadr must be (njnt,)");
    require(static_cast<i64>(a.jnt_qpos0.shape(0)) == nj, "chain jnt_qpos0 must be (njnt,)");
    require(a.frame_pos.shape(0) == 3, "chain frame_pos must be (3,)");
    require(a.frame_rot.shape(0) == 3 && a.frame_rot.shape(1) == 3, "chain frame_rot must be (3, 3)");
    for (i64 j = 0; j < nj; ++j) {
        require(a.jnt_qadr.data()[j] >= 0 && a.jnt_qadr.data()[j] < nq, "chain jnt_qadr out of range of q");
        if (nv >= 0)
            require(a.jnt_dadr.data()[j] >= 0 && a.jnt_dadr.data()[j] < nv, "chain jnt_dadr out of range of the dofs");
    }
    model::Chain& c = a.chain;
    c.nbody = nb_;
    c.njnt = nj;
    c.body_pos = a.body_pos.data();
    c.body_rot = a.body_rot.data();
    c.jnt_start = start;
    c.jnt_type = a.jnt_type.data();
    c.jnt_axis = a.jnt_axis.data();
    c.jnt_pos = a.jnt_pos.data();
    c.jnt_qadr = a.jnt_qadr.data();
    c.jnt_dadr = a.jnt_dadr.data();
    c.jnt_qpos0 = a.jnt_qpos0.data();
    c.frame_pos = a.frame_pos.data();
    c.frame_rot = a.frame_rot.data();
    return a;
}

// A chain's arrays, checked and copied once (qpik._engine.model.Chain). need_q / need_v:
// the smallest q / dof count its joint addresses fit in (checked against each call's
// arrays).
struct ChainData {
    i64 nbody = 0, njnt = 0, need_q = 0, need_v = 0;
    std::vector<double> body_pos, body_rot, jnt_axis, jnt_pos, jnt_qpos0, frame_pos, frame_rot;
    std::vector<i64> jnt_start, jnt_type, jnt_qadr, jnt_dadr;
    model::Chain chain;  // views on the vectors above

    template <class T>
    static std::vector<T> copy(const T* p, size_t n) {
        return std::vector<T>(p, p + n);
    }

    ChainData(nb::handle tuple, i64 nq, i64 nv) {
        require(nq >= 0 && nv >= 0, "nq and nv must be >= 0");
        ChainArgs a = unpack_chain(tuple, nq, nv);
        const model::Chain& c = a.chain;
        nbody = c.nbody;
        njnt = c.njnt;
        size_t nb_ = static_cast<size_t>(nbody), nj = static_cast<size_t>(njnt);
        body_pos = copy(c.body_pos, 3 * nb_);
        body_rot = copy(c.body_rot, 9 * nb_);
        jnt_start = copy(c.jnt_start, nb_ + 1);
        jnt_type = copy(c.jnt_type, nj);
        jnt_axis = copy(c.jnt_axis, 3 * nj);
        jnt_pos = copy(c.jnt_pos, 3 * nj);
        jnt_qadr = copy(c.jnt_qadr, nj);
        jnt_dadr = copy(c.jnt_dadr, nj);
        jnt_qpos0 = copy(c.jnt_qpos0, nj);
        frame_pos = copy(c.frame_pos, 3);
        frame_rot = copy(c.frame_rot, 9);
        for (size_t j = 0; j < nj; ++j) {
            need_q = std::max(need_q, jnt_qadr[j] + 1);
            need_v = std::max(need_v, jnt_dadr[j] + 1);
        }
        model::Chain& v = chain;
        v.nbody = nbody;
        v.njnt = njnt;
        v.body_pos = body_pos.data();
        v.body_rot = body_rot.data();
        v.jnt_start = jnt_start.data();
        v.jnt_type = jnt_type.data();
        v.jnt_axis = jnt_axis.data();
        v.jnt_pos = jnt_pos.data();
        v.jnt_qadr = jnt_qadr.data();
        v.jnt_dadr = jnt_dadr.data();
        v.jnt_qpos0 = jnt_qpos0.data();
        v.frame_pos = frame_pos.data();
        v.frame_rot = frame_rot.data();
    }
    ChainData(const ChainData&) = delete;
    ChainData& operator=(const ChainData&) = delete;

    // The chain for a call with nq coordinates and nv dofs (nv < 0: no dof array).
    const model::Chain& fit(i64 nq, i64 nv) const {
        require(need_q <= nq, "q is too short for the chain's joint coordinates");
        if (nv >= 0) require(need_v <= nv, "the dof arrays are too short for the chain's dofs");
        return chain;
    }
};

// The chain of a kernel's `chain` argument: a ChainData (no copy, no unpacking) or the
// tuple of arrays (unpacked and checked into `holder`).
inline const model::Chain& chain_arg(nb::handle obj, i64 nq, i64 nv, ChainArgs& holder) {
    ChainData* data = nullptr;
    if (nb::try_cast<ChainData*>(obj, data, false) && data != nullptr) return data->fit(nq, nv);
    holder = unpack_chain(obj, nq, nv);
    return holder.chain;
}

inline bool truthy(nb::handle h) {
    int r = PyObject_IsTrue(h.ptr());
    if (r < 0) throw nb::python_error();
    return r != 0;
}

// qpik._engine.model.start_defect and _StartBox.check: (1, i) if x[i] is not finite, (2, i)
// if it is beyond [lo, hi] by more than tol, else (0, -1) with x clipped in place onto the
// box as np.clip(x, lo, hi) (minimum(maximum(x, lo), hi)).
// start_defect_code: the same test and clip, as (code, index) without a Python tuple.
inline i64 start_defect_code(double* x, const double* lo, const double* hi, size_t n, double tol, i64& index) {
    index = -1;
    for (size_t i = 0; i < n; ++i)
        if (!std::isfinite(x[i])) return index = static_cast<i64>(i), 1;
    for (size_t i = 0; i < n; ++i)
        if (x[i] < lo[i] - tol || x[i] > hi[i] + tol) return index = static_cast<i64>(i), 2;
    for (size_t i = 0; i < n; ++i) {
        if (x[i] < lo[i]) x[i] = lo[i];
        if (x[i] > hi[i]) x[i] = hi[i];
    }
    return 0;
}

inline nb::tuple start_defect(double* x, const double* lo, const double* hi, size_t n, double tol) {
    i64 index;
    i64 code = start_defect_code(x, lo, hi, n, tol, index);
    return nb::make_tuple(code, index);
}

}  // namespace qpik::bind

// A model's tree for model::inertia_matrix (the kinetic-energy tasks' M(q)), copied from
// NumPy arrays and checked once: shared by qpik._engine.model.inertia_matrix and the
// compiled step's kernel.
#pragma once

#include <cmath>
#include <vector>

#include "bind.hpp"
#include "model/inertia.hpp"

namespace qpik::bind {

// A model's tree for model::inertia_matrix, copied and checked once (each body's parent
// before it, each dof's body in range, each dof's parent before it or -1, the armature
// finite, a fixed diagonal NaN or finite): a bad tree raises ValueError instead of reading
// out of bounds.
struct OwnedTree {
    std::vector<i64> body_parent, dof_body, dof_parent;
    std::vector<double> armature, fixed;

    OwnedTree() = default;
    OwnedTree(const In<i64, 1>& bp, const In<i64, 1>& db, const In<i64, 1>& dp, const In1& arm, const In1& fix,
              const char* who) {
        const i64 nbody = static_cast<i64>(bp.shape(0)), nv = static_cast<i64>(db.shape(0));
        require(static_cast<i64>(dp.shape(0)) == nv && static_cast<i64>(arm.shape(0)) == nv &&
                    static_cast<i64>(fix.shape(0)) == nv,
                who);  // (the message names the shapes expected)
        require(nbody >= 1, who);
        body_parent.assign(bp.data(), bp.data() + nbody);
        dof_body.assign(db.data(), db.data() + nv);
        dof_parent.assign(dp.data(), dp.data() + nv);
        armature.assign(arm.data(), arm.data() + nv);
        fixed.assign(fix.data(), fix.data() + nv);
        for (i64 b = 1; b < nbody; ++b) require(body_parent[b] >= 0 && body_parent[b] < b, who);
        for (i64 i = 0; i < nv; ++i) {
            require(dof_body[i] > 0 && dof_body[i] < nbody, who);
            require(dof_parent[i] >= -1 && dof_parent[i] < i, who);
            require(std::isfinite(armature[i]) && !std::isinf(fixed[i]), who);
        }
    }

    // The tree as model::inertia_matrix reads it (views of this object's vectors).
    model::InertiaTree view() const {
        return model::InertiaTree{static_cast<i64>(body_parent.size()), static_cast<i64>(dof_body.size()),
                                  body_parent.data(), dof_body.data(), dof_parent.data(), armature.data(),
                                  fixed.data()};
    }
};

}  // namespace qpik::bind

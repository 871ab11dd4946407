// Bindings of the model layer (qpik._engine.model): chain kinematics and rotations.
#include "bind.hpp"
#include "bind_chain.hpp"
#include "bind_tree.hpp"
#include "detmath.hpp"
#include "model/chain.hpp"
#include "model/com.hpp"
#include "model/jac.hpp"
#include "model/so3.hpp"

#include <cmath>
#include <cstring>
#include <vector>

namespace nb = nanobind;
using namespace nb::literals;
using namespace qpik;
using namespace qpik::bind;

namespace {

// The bytes of some arrays at construction, against which unchanged() compares them.
struct ArrayWatch {
    std::vector<const unsigned char*> data;
    std::vector<std::vector<unsigned char>> copies;

    explicit ArrayWatch(nb::list arrays) {
        using Any = nb::ndarray<nb::numpy, nb::c_contig, nb::device::cpu>;
        for (nb::handle h : arrays) {
            Any a;
            if (!nb::try_cast(h, a, false)) throw BadArgument("arrays must be C-contiguous NumPy arrays");
            const auto* p = static_cast<const unsigned char*>(a.data());
            size_t n = a.nbytes();
            data.push_back(p);
            copies.emplace_back(p, p + n);
        }
    }
    bool unchanged() const {
        for (size_t i = 0; i < data.size(); ++i) {
            size_t n = copies[i].size();
            if (n != 0 && std::memcmp(data[i], copies[i].data(), n) != 0) return false;
        }
        return true;
    }
};

}  // namespace

void bind_model(nb::module_& m) {
    m.attr("HINGE") = model::HINGE;
    m.attr("SLIDE") = model::SLIDE;

    nb::class_<ChainData>(m, "Chain",
                          "A kinematic chain's arrays (the tuple of qpik.model.KinematicChain.arrays), "
                          "checked and copied once; every kernel that takes `chain` takes it (or the tuple).")
        .def(nb::init<nb::handle, i64, i64>(), "arrays"_a, "nq"_a, "nv"_a,
             "Check and copy the chain tuple for a model of nq coordinates and nv dofs.")
        .def_ro("nbody", &ChainData::nbody, "Bodies on the chain.")
        .def_ro("njnt", &ChainData::njnt, "Joints on the chain.");

    nb::class_<ArrayWatch>(m, "ArrayWatch",
                           "A copy of some arrays' bytes, to tell whether they changed in place. The "
                           "arrays' memory must outlive every call of unchanged() (it holds no reference).")
        .def(nb::init<nb::list>(), "arrays"_a, "Remember the bytes of C-contiguous arrays (any dtype).")
        .def("unchanged", &ArrayWatch::unchanged, "Whether every array still holds the bytes remembered.");

    m.def(
        "subtree_com_jacobian",
        [](In2 cdof, In2 subtree_com, In<i64, 1> point, In<i64, 1> root, In1 scale, Out2 jac) {
            const i64 nv = static_cast<i64>(cdof.shape(0)), nbody = static_cast<i64>(subtree_com.shape(0));
            require(cdof.shape(1) == 6, "cdof must be (nv, 6)");
            require(subtree_com.shape(1) == 3, "subtree_com must be (nbody, 3)");
            require(static_cast<i64>(point.shape(0)) == nv && static_cast<i64>(root.shape(0)) == nv &&
                        static_cast<i64>(scale.shape(0)) == nv,
                    "point, root and scale must be (nv,)");
            require(jac.shape(0) == 3 && static_cast<i64>(jac.shape(1)) == nv, "jac must be (3, nv)");
            for (i64 d = 0; d < nv; ++d)
                require(scale(d) == 0.0 || (point(d) >= 0 && point(d) < nbody && root(d) >= 0 && root(d) < nbody),
                        "point and root must be body ids (where scale is not 0)");
            model::subtree_com_jacobian(cdof.data(), subtree_com.data(), nv, point.data(), root.data(), scale.data(),
                                        jac.data());
        },
        "cdof"_a, "subtree_com"_a, "point"_a, "root"_a, "scale"_a, "jac"_a.noconvert(),
        "The Jacobian jac (3, nv) [m per unit of dq], world frame, of a subtree's centre of mass from "
        "mjData's cdof and subtree_com and its per-dof chain (qpik.model.com.subtree_com_chain), written in "
        "place: column d = scale[d] (v_d + omega_d x (subtree_com[point[d]] - subtree_com[root[d]])).");

    m.def(
        "fk_jac",
        [](nb::handle chain, In1 q, Out1 position, Out2 rotation, Out2 jac, nb::handle want_jac) {
            bool want = truthy(want_jac);
            require(position.shape(0) == 3, "position must be (3,)");
            require(rotation.shape(0) == 3 && rotation.shape(1) == 3, "rotation must be (3, 3)");
            require(jac.shape(0) == 6, "jac must be (6, nv)");
            ChainArgs holder;
            const model::Chain& c =
                chain_arg(chain, static_cast<i64>(q.shape(0)), want ? static_cast<i64>(jac.shape(1)) : -1, holder);
            model::fk_jac(c, q.data(), position.data(), rotation.data(), mat(jac), want);
        },
        "chain"_a, "q"_a, "position"_a.noconvert(), "rotation"_a.noconvert(), "jac"_a.noconvert(),
        "want_jac"_a,
        "Pose of the chain's frame at q (position (3,) [m], rotation (3, 3)) and, if want_jac, its "
        "world-aligned Jacobian jac (6, nv) [v; omega], written in place.");

    m.def(
        "start_defect",
        [](Out1 q, In1 lower, In1 upper, double tol) {
            size_t n = q.shape(0);
            require(lower.shape(0) == n && upper.shape(0) == n, "lower and upper must be (n,) like q");
            return start_defect(q.data(), lower.data(), upper.data(), n, tol);
        },
        "q"_a.noconvert(), "lower"_a, "upper"_a, "tol"_a,
        "Check a start q against the joint limits: (1, i) for the first entry not finite, (2, i) "
        "for the first outside [lower - tol, upper + tol], else (0, -1) with q clipped into "
        "[lower, upper] in place.");

    m.def(
        "reach_radius",
        [](nb::handle chain, In1 q, Out1 center) {
            require(center.shape(0) == 3, "center must be (3,)");
            ChainArgs holder;
            const model::Chain& c = chain_arg(chain, static_cast<i64>(q.shape(0)), -1, holder);
            return model::reach_radius(c, q.data(), center.data());
        },
        "chain"_a, "q"_a, "center"_a.noconvert(),
        "Length of the path through the feet of the common perpendiculars of consecutive hinge "
        "axes at q (to the frame); center receives its start.");

    m.def(
        "hessian_weights",
        [](In2 jac, In2 weights, In<i64, 1> chain, Out1 out) {
            const i64 n = static_cast<i64>(jac.shape(1));
            require(jac.shape(0) == 6 && weights.shape(0) == 6 && static_cast<i64>(weights.shape(1)) == n &&
                        static_cast<i64>(out.shape(0)) == n,
                    "jac and weights must be (6, nv), out (nv,)");
            const i64 m = static_cast<i64>(chain.shape(0));
            for (i64 e = 0; e < m; ++e)
                require(chain.data()[e] >= 0 && chain.data()[e] < n, "chain's dofs must be in [0, nv)");
            model::hessian_weights(jac.data(), weights.data(), n, chain.data(), m, out.data());
        },
        "jac"_a, "weights"_a, "chain"_a, "out"_a.noconvert(),
        "<dJ/dq_a, W> for every dof a into out (nv,): jac (6, nv) [v; omega] a frame's Jacobian, "
        "weights (6, nv), chain the dofs of a chain of hinges and slides, root first (the kinematic "
        "Hessian in closed form; 0 off the chain).");

    m.def(
        "inertia_matrix",
        [](In2 cinert, In2 cdof, In<i64, 1> body_parent, In<i64, 1> dof_body, In<i64, 1> dof_parent,
           In1 armature, In1 fixed) {
            const bind::OwnedTree t(body_parent, dof_body, dof_parent, armature, fixed,
                                    "inertia_matrix: body_parent (nbody,), dof_body, dof_parent and armature "
                                    "(nv,) must describe a MuJoCo model's tree");
            const i64 nbody = static_cast<i64>(body_parent.shape(0)), n = static_cast<i64>(dof_body.shape(0));
            require(static_cast<i64>(cinert.shape(0)) == nbody && cinert.shape(1) == 10 &&
                        static_cast<i64>(cdof.shape(0)) == n && cdof.shape(1) == 6,
                    "inertia_matrix: cinert must be (nbody, 10), cdof (nv, 6)");
            std::vector<double> crb(static_cast<size_t>(10 * nbody)), M(static_cast<size_t>(n * n));
            model::inertia_matrix(t.view(), cinert.data(), cdof.data(), crb.data(), M.data());
            const size_t un = static_cast<size_t>(n);
            return to_numpy(std::move(M), {un, un});
        },
        "cinert"_a, "cdof"_a, "body_parent"_a, "dof_body"_a, "dof_parent"_a, "armature"_a, "fixed"_a,
        "The joint-space inertia matrix (nv, nv) from an MjData's cinert and cdof (mj_comPos) by the "
        "composite rigid body algorithm (mj_crb's operations: bitwise MuJoCo's M), the armature added on the "
        "diagonal; fixed (nv,): a simple dof's constant diagonal (dof_M0), NaN for the others.");

    m.def(
        "quat2mat",
        [](In2 quat) {
            require(quat.shape(1) == 4, "quat must be (k, 4)");
            size_t k = quat.shape(0);
            std::vector<double> out(9 * k);
            model::quat2mat(quat.data(), static_cast<i64>(k), out.data());
            return to_numpy(std::move(out), {k, 3, 3});
        },
        "quat"_a, "Rotation matrices (k, 3, 3) of unit quaternions (k, 4) (w, x, y, z).");

    m.def(
        "rotation_log",
        [](In2 R, Out1 out) {
            require(R.shape(0) == 3 && R.shape(1) == 3, "R must be (3, 3)");
            require(out.shape(0) == 3, "out must be (3,)");
            return model::rotation_log(R.data(), out.data());
        },
        "R"_a, "out"_a.noconvert(), "Rotation vector of R into out; returns the angle [rad].");

    m.def(
        "rotation_defect",
        [](In2 R) {
            require(R.shape(0) == 3 && R.shape(1) == 3, "R must be (3, 3)");
            return model::rotation_defect(R.data());
        },
        "R"_a, "max |R R^T - I|, or inf when an entry is not finite or det R <= 0.");

    m.def(
        "target_defect",
        [](In1 position, In2 rotation, nb::handle has_rot) {
            require(position.shape(0) == 3, "position must be (3,)");
            require(rotation.shape(0) == 3 && rotation.shape(1) == 3, "rotation must be (3, 3)");
            return model::target_defect(position.data(), rotation.data(), truthy(has_rot));
        },
        "position"_a, "rotation"_a, "has_rot"_a,
        "0 for a valid target; 1: position not finite; 2: rotation not finite; 3: not a rotation.");

    m.def(
        "left_jacobian_inverse",
        [](In1 phi, Out2 out) {
            require(phi.shape(0) == 3, "phi must be (3,)");
            require(out.shape(0) == 3 && out.shape(1) == 3, "out must be (3, 3)");
            model::so3_ljacinv(out.data(), phi.data());
        },
        "phi"_a, "out"_a.noconvert(), "Inverse left Jacobian of SO(3) at rotation vector phi, into out.");

    m.def(
        "sincos",
        [](In1 x, Out1 s, Out1 c) {
            require(s.shape(0) == x.shape(0) && c.shape(0) == x.shape(0), "s and c must have x's shape (n,)");
            for (size_t i = 0; i < x.shape(0); ++i) dm::sincos(x.data()[i], s.data()[i], c.data()[i]);
        },
        "x"_a, "s"_a.noconvert(), "c"_a.noconvert(),
        "The engine's sin and cos of each x [rad] into s and c (detmath.hpp: the same bits on every "
        "machine, within about an ulp).");

    m.def(
        "atan2",
        [](In1 y, In1 x, Out1 out) {
            require(x.shape(0) == y.shape(0) && out.shape(0) == y.shape(0), "y, x and out must have one shape (n,)");
            for (size_t i = 0; i < y.shape(0); ++i) out.data()[i] = dm::atan2(y.data()[i], x.data()[i]);
        },
        "y"_a, "x"_a, "out"_a.noconvert(),
        "The engine's atan2 of each (y, x) [rad] into out (detmath.hpp: C99's special values).");
}

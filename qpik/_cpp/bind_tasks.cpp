// Bindings of the tasks layer (qpik._engine.tasks): SO(3)/SE(3) (model/so3.hpp and
// model/se3.hpp, wrapped by qpik.model.lie), the frame task's kernels (tasks/frame.hpp,
// used by qpik.tasks.frame) and the linear residual (tasks/linear.hpp, qpik.tasks.coupling). The Lie routines write into their first argument.
#include <cmath>

#include "bind.hpp"

#include <nanobind/stl/optional.h>
#include "model/se3.hpp"
#include "tasks/frame.hpp"
#include "tasks/linear.hpp"
#include "tasks/axis_align.hpp"
#include "tasks/look_at.hpp"
#include "tasks/pose.hpp"
#include "tasks/joint_limits.hpp"
#include "tasks/kinetic.hpp"
#include "tasks/manipulability.hpp"
#include "tasks/equality.hpp"

namespace nb = nanobind;
using namespace qpik;
using namespace qpik::bind;

namespace {

const double* at_least(const In1& x, size_t n, const char* what) {
    require(x.shape(0) >= n, what);
    return x.data();
}

double* exactly(Out1& x, size_t n, const char* what) {
    require(x.shape(0) == n, what);
    return x.data();
}

}  // namespace

void bind_tasks(nb::module_& m) {
    m.attr("EPS") = model::kLieEps;

    m.def(
        "so3_log",
        [](Out1 omega, In1 wxyz) {
            model::so3_log(exactly(omega, 3, "so3_log: omega must have shape (3,)"),
                           at_least(wxyz, 4, "so3_log: wxyz must have at least 4 entries"));
        },
        nb::arg("omega").noconvert(), nb::arg("wxyz"),
        "Rotation vector [rad] of a unit quaternion (w, x, y, z), written into omega (3,).");
    m.def(
        "so3_ljacinv",
        [](Out1 out, In1 omega) {
            model::so3_ljacinv(exactly(out, 9, "so3_ljacinv: out must have shape (9,)"),
                               at_least(omega, 3, "so3_ljacinv: omega must have 3 entries"));
        },
        nb::arg("out").noconvert(), nb::arg("omega"),
        "SO(3) left Jacobian inverse at omega, row-major 3x3 into out (9,).");
    m.def(
        "xmat_xpos_to_wxyz_xyz",
        [](Out1 out, In1 xmat, In1 xpos) {
            model::xmat_xpos_to_wxyz_xyz(
                exactly(out, 7, "xmat_xpos_to_wxyz_xyz: out must have shape (7,)"),
                at_least(xmat, 9, "xmat_xpos_to_wxyz_xyz: xmat must have 9 entries"),
                at_least(xpos, 3, "xmat_xpos_to_wxyz_xyz: xpos must have 3 entries"));
        },
        nb::arg("out").noconvert(), nb::arg("xmat"), nb::arg("xpos"),
        "A MuJoCo frame (xmat row-major (9,), xpos (3,)) as wxyz_xyz, into out (7,).");
    m.def(
        "se3_log",
        [](Out1 tangent, In1 T) {
            model::se3_log(exactly(tangent, 6, "se3_log: tangent must have shape (6,)"),
                           at_least(T, 7, "se3_log: T must have 7 entries"));
        },
        nb::arg("tangent").noconvert(), nb::arg("T"), "log(T) as [v; omega], into tangent (6,).");
    m.def(
        "se3_inverse_multiply",
        [](Out1 out, In1 a, In1 b) {
            model::se3_inverse_multiply(
                exactly(out, 7, "se3_inverse_multiply: out must have shape (7,)"),
                at_least(a, 7, "se3_inverse_multiply: a must have 7 entries"),
                at_least(b, 7, "se3_inverse_multiply: b must have 7 entries"));
        },
        nb::arg("out").noconvert(), nb::arg("a"), nb::arg("b"), "out = a^-1 b (wxyz_xyz).");
    m.def(
        "se3_rminus",
        [](Out1 tangent, In1 a, In1 b) {
            model::se3_rminus(exactly(tangent, 6, "se3_rminus: tangent must have shape (6,)"),
                              at_least(a, 7, "se3_rminus: a must have 7 entries"),
                              at_least(b, 7, "se3_rminus: b must have 7 entries"));
        },
        nb::arg("tangent").noconvert(), nb::arg("a"), nb::arg("b"),
        "a (-) b = log(b^-1 a), into tangent (6,).");
    m.def(
        "se3_jlog",
        [](Out2 jlog, In1 T) {
            require(jlog.shape(0) == 6 && jlog.shape(1) == 6, "se3_jlog: jlog must have shape (6, 6)");
            model::se3_jlog(jlog.data(), at_least(T, 7, "se3_jlog: T must have 7 entries"));
        },
        nb::arg("jlog").noconvert(), nb::arg("T"),
        "jlog(T): the right Jacobian inverse at log(T), into jlog (6, 6).");

    m.def(
        "inverse_manipulability",
        [](In2 jac, In<i64, 1> rows, In<i64, 1> chain, std::optional<In<i64, 1>> threshold) {
            const i64 n = static_cast<i64>(jac.shape(1)), m = static_cast<i64>(rows.shape(0));
            const i64 count = static_cast<i64>(chain.shape(0));
            if (threshold)
                require(static_cast<i64>(threshold->shape(0)) == n,
                        "inverse_manipulability: threshold must have shape (nv,)");
            require(jac.shape(0) == 6, "inverse_manipulability: jac must have shape (6, nv)");
            for (i64 r = 0; r < m; ++r)
                require(rows.data()[r] >= 0 && rows.data()[r] < 6, "inverse_manipulability: rows must be in [0, 6)");
            for (i64 e = 0; e < count; ++e)
                require(chain.data()[e] >= 0 && chain.data()[e] < n,
                        "inverse_manipulability: chain's dofs must be in [0, nv)");
            require(count <= n, "inverse_manipulability: the chain has more dofs than nv");
            std::vector<double> scratch(static_cast<size_t>(tasks::manipulability_scratch(m, n))),
                de(static_cast<size_t>(n)), singular(static_cast<size_t>(m));
            double value = 0.0;
            const double e = tasks::inverse_manipulability(jac.data(), n, rows.data(), m, chain.data(), count, 1,
                                                           scratch.data(), de.data(), &value, singular.data(),
                                                           threshold ? threshold->data() : nullptr);
            if (m > n) singular.clear();
            return std::make_tuple(e, to_numpy(std::move(de)), value, to_numpy(std::move(singular)));
        },
        nb::arg("jac"), nb::arg("rows"), nb::arg("chain"), nb::arg("threshold") = nb::none(),
        "(e, de/dq (nv,), m, singular values (rows' order)) of a manipulability task: e = 1 / m(q), m the "
        "manipulability of the rows `rows` of the world-aligned frame Jacobian jac (6, nv) [v; omega], on the "
        "frame's chain `chain` (its dofs, root first): of hinges and slides where threshold is None, else any, "
        "threshold (nv,) each dof's (qpik.model.gradients.motion_chain); e = 0, a zero gradient and m = 0 where "
        "the task is idle (more rows than dofs, a rank deficient to 1e-9, 1 / m^2 not finite).");

    m.def(
        "equality_rows",
        [](In1 J, In1 pos, In<std::int32_t, 1> type, In<std::int32_t, 1> id, In<std::int32_t, 1> rownnz,
           In<std::int32_t, 1> rowadr, In<std::int32_t, 1> colind, bool sparse, i64 nv, In<i64, 1> position,
           In1 cost, double gain, double lm) {
            const i64 nefc = static_cast<i64>(pos.shape(0)), size = static_cast<i64>(J.shape(0));
            const i64 neq = static_cast<i64>(position.shape(0));
            require(nv >= 0, "equality_rows: nv must be >= 0");
            const tasks::EfcRows efc{nefc, nv, sparse, J.data(), pos.data(), type.data(), id.data(),
                                     rownnz.data(), rowadr.data(), colind.data()};
            const auto len = [](const auto& x) { return static_cast<i64>(x.shape(0)); };
            require(tasks::efc_rows_fit(efc, size, len(type), len(id), len(rownnz), len(rowadr), len(colind)),
                    "equality_rows: MuJoCo's constraint arrays do not fit (efc_type and efc_id nefc entries; "
                    "sparse, each row within efc_J and its columns in [0, nv); dense, efc_J nefc * nv long)");
            for (i64 e = 0; e < neq; ++e)
                require(position.data()[e] >= -1 && position.data()[e] < static_cast<i64>(cost.shape(0)),
                        "equality_rows: a position is out of range of cost");
            std::vector<double> A(static_cast<size_t>(nefc * nv)), b(static_cast<size_t>(nefc)),
                w(static_cast<size_t>(nefc));
            double mu = 0.0;
            const i64 k = tasks::equality_rows_into(MatRef(A.data(), nefc, nv), b.data(), w.data(), 0, nefc, efc,
                                                    position.data(), neq, cost.data(), gain, lm, mu);
            A.resize(static_cast<size_t>(k * nv));
            b.resize(static_cast<size_t>(k));
            w.resize(static_cast<size_t>(k));
            return std::make_tuple(to_numpy(std::move(A), {static_cast<size_t>(k), static_cast<size_t>(nv)}),
                                   to_numpy(std::move(b)), mu, to_numpy(std::move(w)));
        },
        nb::arg("efc_J"), nb::arg("efc_pos"), nb::arg("efc_type"), nb::arg("efc_id"), nb::arg("efc_J_rownnz"),
        nb::arg("efc_J_rowadr"), nb::arg("efc_J_colind"), nb::arg("sparse"), nb::arg("nv"), nb::arg("position"),
        nb::arg("cost"), nb::arg("gain"), nb::arg("lm"),
        "An equality-constraint task's weighted rows (A (k, nv), b (k,), lm |b|^2, the rows' costs (k,)) from "
        "an MjData's constraint rows (mj_makeConstraint): its equalities' rows in efc order (position (neq,): "
        "each equality's position in the task, -1 where not its; cost by position).");

    m.def(
        "kinetic_rows",
        [](In2 M, double scale) -> nb::object {
            const i64 n = static_cast<i64>(M.shape(0));
            require(static_cast<i64>(M.shape(1)) == n, "kinetic_rows: M must be square (nv, nv)");
            std::vector<double> A(static_cast<size_t>(n * n)), b(static_cast<size_t>(n)), L(A.size());
            if (!tasks::kinetic_rows_into(MatRef(A.data(), n, n), b.data(), 0, M.data(), n, scale, L.data()))
                return nb::none();
            const size_t un = static_cast<size_t>(n);
            return nb::cast(to_numpy(std::move(A), {un, un}));
        },
        nb::arg("M"), nb::arg("scale"),
        "Rows A (nv, nv) with A^T A = scale M (A = L^T, the Cholesky factor of scale M; b = 0): a "
        "kinetic-energy task's (zeros where scale is 0); None where scale M is not positive definite "
        "with every pivot^2 above 1e-12 max(1, max diag) or scale is not a finite number >= 0.");

    m.def(
        "frame_error_jlog",
        [](In1 xmat, In1 xpos, In1 target) {
            const double* R = at_least(xmat, 9, "frame_error_jlog: xmat must have 9 entries");
            const double* p = at_least(xpos, 3, "frame_error_jlog: xpos must have 3 entries");
            const double* t = at_least(target, 7, "frame_error_jlog: target must have 7 entries");
            Vec error(6), jlog(36);
            tasks::frame_error_jlog(R, p, t, error.data(), jlog.data());
            return std::make_tuple(to_numpy(std::move(error)), to_numpy(std::move(jlog), {6, 6}));
        },
        nb::arg("xmat"), nb::arg("xpos"), nb::arg("target"),
        "mink's frame-task error log(T_fw^-1 T_tw) (6,) and jlog(T_tw^-1 T_fw) (6, 6) of the "
        "frame at (xpos, xmat) and its target (wxyz_xyz).");
    m.def(
        "frame_rows_into",
        [](Out2 A, Out1 b, i64 row, In2 jac, In1 xmat, In2 jlog, In1 error, In1 cost, double gain,
           double lm_damping) {
            const i64 nv = static_cast<i64>(jac.shape(1));
            require(jac.shape(0) == 6, "frame_rows_into: jac must have shape (6, nv)");
            require(static_cast<i64>(A.shape(1)) == nv, "frame_rows_into: A must have nv columns");
            require(row >= 0 && row + 6 <= static_cast<i64>(A.shape(0)) &&
                        row + 6 <= static_cast<i64>(b.shape(0)),
                    "frame_rows_into: rows row:row+6 must lie in A and b");
            require(jlog.shape(0) == 6 && jlog.shape(1) == 6, "frame_rows_into: jlog must have shape (6, 6)");
            require(xmat.shape(0) >= 9 && error.shape(0) >= 6 && cost.shape(0) >= 6,
                    "frame_rows_into: xmat (9,), error (6,) and cost (6,) expected");
            return tasks::frame_rows_into(mat(A), b.data(), row, cmat(jac), xmat.data(), jlog.data(),
                                          error.data(), cost.data(), gain, lm_damping);
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("row"), nb::arg("jac"),
        nb::arg("xmat"), nb::arg("jlog"), nb::arg("error"), nb::arg("cost"), nb::arg("gain"),
        nb::arg("lm_damping"),
        "Rows row:row+6 of a frame task into A, b: A = diag(cost) (-jlog) [R^T Jp; R^T Jr], "
        "b = -gain cost e; returns lm_damping |b|^2.");
    m.attr("POSE_POSITION") = static_cast<i64>(tasks::POSE_POSITION);
    m.attr("POSE_ORIENTATION") = static_cast<i64>(tasks::POSE_ORIENTATION);
    m.attr("POSE_FULL") = static_cast<i64>(tasks::POSE_FULL);
    m.def(
        "pose_rows_into",
        [](Out2 A, Out1 b, i64 row, In2 jac, In1 xpos, In1 xmat, In1 target, i64 part, In1 cost, double gain,
           double lm_damping) {
            require(part == tasks::POSE_POSITION || part == tasks::POSE_ORIENTATION || part == tasks::POSE_FULL,
                    "pose_rows_into: part must be 1 (position), 2 (orientation) or 3 (both)");
            const i64 k = tasks::pose_part_rows(part);
            const i64 nv = static_cast<i64>(jac.shape(1));
            require(jac.shape(0) == 6, "pose_rows_into: jac must have shape (6, nv)");
            require(static_cast<i64>(A.shape(1)) == nv, "pose_rows_into: A must have nv columns");
            require(row >= 0 && row + k <= static_cast<i64>(A.shape(0)) &&
                        row + k <= static_cast<i64>(b.shape(0)),
                    "pose_rows_into: rows row:row+k must lie in A and b");
            require(xpos.shape(0) >= 3 && xmat.shape(0) >= 9 && target.shape(0) >= tasks::kPoseTarget,
                    "pose_rows_into: xpos (3,), xmat (9,) and target (12,) expected");
            require(static_cast<i64>(cost.shape(0)) == k, "pose_rows_into: cost must have one entry per row");
            return tasks::pose_rows_into(mat(A), b.data(), row, cmat(jac), xpos.data(), xmat.data(), target.data(),
                                         part, cost.data(), gain, lm_damping);
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("row"), nb::arg("jac"), nb::arg("xpos"),
        nb::arg("xmat"), nb::arg("target"), nb::arg("part"), nb::arg("cost"), nb::arg("gain"), nb::arg("lm_damping"),
        "Rows row:row+k of a world-frame pose task (part 1 position, 2 orientation, 3 both; k = 3, 3, 6) into "
        "A, b: A = diag(cost) [Jv; Jl^-1(e_rot) Jw], b = -gain cost e, e = [p - p*; log(R R*^T)] (world frame); "
        "target = p* (3) then R* (row-major 9). Returns lm_damping |b|^2.");
    m.def(
        "joint_limit_distance_row",
        [](Out2 A, Out1 b, i64 row, In1 qpos, In<i64, 1> qadr, In<i64, 1> dofs, In1 half, In1 mid_over_half, double n, double cost,
           double gain, double lm_damping) {
            const i64 m = static_cast<i64>(qadr.shape(0));
            const i64 nv = static_cast<i64>(A.shape(1)), nq = static_cast<i64>(qpos.shape(0));
            require(row >= 0 && row < static_cast<i64>(A.shape(0)) && row < static_cast<i64>(b.shape(0)),
                    "joint_limit_distance_row: row must lie in A and b");
            require(static_cast<i64>(dofs.shape(0)) == m && static_cast<i64>(half.shape(0)) == m &&
                        static_cast<i64>(mid_over_half.shape(0)) == m,
                    "joint_limit_distance_row: qadr, dofs, half and mid_over_half must have one entry per joint");
            for (i64 k = 0; k < m; ++k)
                require(qadr.data()[k] >= 0 && qadr.data()[k] < nq && dofs.data()[k] >= 0 && dofs.data()[k] < nv,
                        "joint_limit_distance_row: a qpos address or dof is out of range");
            auto joint = [&](i64 k, i64& adr, i64& dof, double& h, double& moh) {
                adr = qadr.data()[k];
                dof = dofs.data()[k];
                h = half.data()[k];
                moh = mid_over_half.data()[k];
                return true;
            };
            double w = 0.0;
            const double mu = tasks::joint_limit_distance_row(mat(A), b.data(), row, qpos.data(), m, joint, n, cost,
                                                              gain, lm_damping, &w);
            return std::make_tuple(mu, w);
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("row"), nb::arg("qpos"), nb::arg("qadr"),
        nb::arg("dofs"), nb::arg("half"), nb::arg("mid_over_half"), nb::arg("n"), nb::arg("cost"), nb::arg("gain"),
        nb::arg("lm_damping"),
        "Row `row` of the joint-limit distance task into A, b (A = cost dw/dq, b = -gain cost w) from the limited "
        "joints' qpos addresses, dofs, half ranges and mid / half (joint order) and n, the scalar joints counted; "
        "returns (lm_damping b^2, w).");
    m.def(
        "linear_residual",
        [](In2 form, In1 qpos) {
            const i64 nq = static_cast<i64>(qpos.shape(0));
            require(static_cast<i64>(form.shape(1)) == nq + 1,
                    "linear_residual: form must have shape (k, nq + 1), nq = len(qpos)");
            Vec r(form.shape(0));
            tasks::linear_residual(cmat(form), qpos.data(), r.data());
            return to_numpy(std::move(r));
        },
        nb::arg("form"), nb::arg("qpos"),
        "r = form[:, :nq] @ qpos - form[:, nq] (k,), summed in the order of qpos (the compiled "
        "step's arithmetic).");
    m.def(
        "look_at_residual",
        [](Out2 A, Out1 b, In2 jac, In1 xmat, In1 xpos, In1 target, In1 axis, In1 cost, double gain,
           double lm_damping, double eps) {
            const size_t nv = jac.shape(1);
            require(jac.shape(0) == 6, "look_at_residual: jac must have shape (6, nv)");
            require(A.shape(0) == 3 && A.shape(1) == nv, "look_at_residual: A must have shape (3, nv)");
            require(b.shape(0) == 3, "look_at_residual: b must have shape (3,)");
            require(xmat.shape(0) == 9, "look_at_residual: xmat must have shape (9,)");
            for (const In1* x : {&xpos, &target, &axis, &cost})
                require(x->shape(0) == 3, "look_at_residual: xpos, target, axis and cost must have shape (3,)");
            return tasks::look_at_residual(jac.data(), static_cast<i64>(nv), xmat.data(), xpos.data(),
                                           target.data(), axis.data(), cost.data(), gain, lm_damping, eps,
                                           A.data(), b.data());
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("jac"), nb::arg("xmat"), nb::arg("xpos"),
        nb::arg("target"), nb::arg("axis"), nb::arg("cost"), nb::arg("gain"), nb::arg("lm_damping"),
        nb::arg("eps"),
        "mink's LookAtTask's weighted residual from a frame's world-aligned Jacobian jac (6, nv),\n"
        "rotation xmat (9,) and position xpos (3,) [m]: A = cost J (3, nv) and b = -cost gain e\n"
        "(3,) written; returns mu = lm_damping |b|^2 (tasks/look_at.hpp).");
    m.def(
        "axis_align_residual",
        [](Out2 A, Out1 b, In2 jacr, In1 xmat, In1 target, In1 axis, In1 cost, double gain, double lm_damping) {
            const size_t nv = jacr.shape(1);
            require(jacr.shape(0) == 3, "axis_align_residual: jacr must have shape (3, nv)");
            require(A.shape(0) == 3 && A.shape(1) == nv, "axis_align_residual: A must have shape (3, nv)");
            require(b.shape(0) == 3, "axis_align_residual: b must have shape (3,)");
            require(xmat.shape(0) == 9, "axis_align_residual: xmat must have shape (9,)");
            for (const In1* x : {&target, &axis, &cost})
                require(x->shape(0) == 3, "axis_align_residual: target, axis and cost must have shape (3,)");
            return tasks::axis_align_residual(jacr.data(), static_cast<i64>(nv), xmat.data(), target.data(),
                                              axis.data(), cost.data(), gain, lm_damping, A.data(), b.data());
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("jacr"), nb::arg("xmat"), nb::arg("target"),
        nb::arg("axis"), nb::arg("cost"), nb::arg("gain"), nb::arg("lm_damping"),
        "mink's AxisAlignTask's weighted residual from a frame's world-aligned rotation Jacobian\n"
        "jacr (3, nv) and rotation xmat (9,): e = axis - R^T target, J = -[R^T target]x R^T jacr,\n"
        "A = cost J (3, nv) and b = -cost gain e (3,) written; returns mu = lm_damping |b|^2\n"
        "(tasks/axis_align.hpp).");
    m.def(
        "unit_rows",
        [](Out2 A, Out1 b, In2 J, In1 e, double gain) {
            const size_t k = J.shape(0), nv = J.shape(1);
            require(e.shape(0) == k, "unit_rows: e must have shape (k,), k the rows of J");
            require(A.shape(0) == k && A.shape(1) == nv, "unit_rows: A must have J's shape");
            require(b.shape(0) == k, "unit_rows: b must have shape (k,)");
            const double* j = J.data();
            const double* ev = e.data();
            for (size_t t = 0; t < k * nv; ++t)
                if (!std::isfinite(j[t])) return false;
            for (size_t i = 0; i < k; ++i)
                if (!std::isfinite(-gain * ev[i])) return false;
            for (size_t i = 0; i < k; ++i) {
                const double* r = j + i * nv;
                double sq = 0.0;
                for (size_t c = 0; c < nv; ++c) sq += r[c] * r[c];
                const double norm = std::sqrt(sq);
                const double s = norm > 0.0 ? 1.0 / norm : 1.0;
                double* a = A.data() + i * nv;
                for (size_t c = 0; c < nv; ++c) a[c] = r[c] * s;
                b.data()[i] = (-gain * ev[i]) * s;
            }
            return true;
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("J"), nb::arg("e"), nb::arg("gain"),
        "Equality rows J dq = -gain e scaled to unit norm: A = s J and b = s (-gain e) written,\n"
        "s = 1 / |J_i| per row (1 for a zero row; |J_i| by its squares summed in order). False,\n"
        "with nothing written, where an entry of J or of -gain e is not finite.");
}

// Bindings of the diffik layer (qpik._engine.diffik): the one-call IK step (diffik/fused.hpp,
// re-exported by qpik._fused). Same names and Python signatures as the numba kernels they
// replace. Every shape and index is checked here (a bad plan raises ValueError, never
// reads out of bounds); the plan's and MuJoCo's arrays are used in place (no copies).
#include "bind.hpp"
#include "diffik/fused.hpp"

#include <algorithm>

namespace nb = nanobind;
using namespace qpik;
using namespace qpik::bind;

namespace {

using I1 = nb::ndarray<const i64, nb::numpy, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using I2 = nb::ndarray<const i64, nb::numpy, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using B2 = nb::ndarray<const i8, nb::numpy, nb::ndim<2>, nb::c_contig, nb::device::cpu>;

template <class X>
i64 dim(const X& x, size_t k) { return static_cast<i64>(x.shape(k)); }

VecRefT<const i64> ivec(const I1& x) { return VecRefT<const i64>(x.data(), dim(x, 0)); }
MatRefT<const i64> imat(const I2& x) { return MatRefT<const i64>(x.data(), dim(x, 0), dim(x, 1)); }

void check_dofs(VecRefT<const i64> dofs, i64 n, const char* what) {
    for (i64 e = 0; e < dofs.n; ++e) require(dofs[e] >= 0 && dofs[e] < n, what);
}

// The views of fused_rows' / fused_step's arguments, after checking every shape and index.
diffik::FusedArgs make_args(Out2& A, Out1& b, Out1& w, const I1& starts, const I2& tasks,
                            const In3& jac, const I2& frames, const In2& site_xpos,
                            const In2& site_xmat, const In2& xpos, const In2& xmat,
                            const In2& geom_xpos, const In2& geom_xmat, const In2& frame_data,
                            const In1& qpos, const In2& posture_data, const I1& cfg_dof,
                            const In2& cfg_data, const I1& vel_dof, const In1& vel_limit,
                            const In1& settings) {
    const i64 n = dim(qpos, 0);
    const i64 M = dim(A, 0);
    require(dim(A, 1) == n, "fused: A must have shape (M, nv) with nv = len(qpos)");
    require(dim(b, 0) == M && dim(w, 0) == M, "fused: b and w must have shape (M,)");
    const i64 L = dim(starts, 0) - 1;
    require(L >= 0, "fused: starts must have L + 1 >= 1 entries");
    const i64* s = starts.data();
    require(s[0] == 0 && s[L] == M, "fused: starts must run from 0 to M");
    for (i64 k = 0; k < L; ++k) require(s[k] <= s[k + 1], "fused: starts must not decrease");
    const i64 F = dim(frames, 0), P = dim(posture_data, 0);
    require(dim(frames, 1) == 2, "fused: frames must have shape (F, 2)");
    require(dim(jac, 0) == F && dim(jac, 1) == 6 && dim(jac, 2) == n,
            "fused: jac must have shape (F, 6, nv)");
    require(dim(frame_data, 0) == F && dim(frame_data, 1) == diffik::kFrameData,
            "fused: frame_data must have shape (F, 15)");
    require(dim(posture_data, 1) >= 2 * n + 2, "fused: posture_data must have shape (P, nq + nv + 2)");
    require(dim(site_xpos, 1) == 3 && dim(xpos, 1) == 3 && dim(geom_xpos, 1) == 3,
            "fused: the positions must have shape (*, 3)");
    require(dim(site_xmat, 1) == 9 && dim(xmat, 1) == 9 && dim(geom_xmat, 1) == 9,
            "fused: the rotations must have shape (*, 9)");
    const i64 count[3] = {std::min(dim(site_xpos, 0), dim(site_xmat, 0)),
                          std::min(dim(xpos, 0), dim(xmat, 0)),
                          std::min(dim(geom_xpos, 0), dim(geom_xmat, 0))};
    const i64* fr = frames.data();
    for (i64 f = 0; f < F; ++f) {
        const i64 kind = fr[2 * f], fid = fr[2 * f + 1];
        require(kind >= 0 && kind <= 2, "fused: a frame kind is not 0 (site), 1 (body) or 2 (geom)");
        require(fid >= 0 && fid < count[kind], "fused: a frame id is out of range of its poses");
    }
    require(dim(tasks, 1) == 4, "fused: tasks must have shape (T, 4)");
    const i64* t = tasks.data();
    for (i64 k = 0; k < dim(tasks, 0); ++k) {
        const i64 kind = t[4 * k], index = t[4 * k + 1], level = t[4 * k + 2], row = t[4 * k + 3];
        require(kind == 0 || kind == 1, "fused: a task kind is not 0 (frame) or 1 (posture)");
        require(index >= 0 && index < (kind == 0 ? F : P), "fused: a task index is out of range");
        require(level >= 0 && level < L, "fused: a task level is out of range");
        const i64 size = kind == 0 ? 6 : n;
        require(row >= 0 && row + size <= M, "fused: a task's rows are out of range of A");
    }
    require(dim(cfg_data, 0) == dim(cfg_dof, 0) && dim(cfg_data, 1) == 3,
            "fused: cfg_data must have shape (len(cfg_dof), 3)");
    check_dofs(ivec(cfg_dof), n, "fused: a cfg_dof entry is out of range");
    require(dim(vel_limit, 0) == dim(vel_dof, 0), "fused: vel_limit must have len(vel_dof) entries");
    check_dofs(ivec(vel_dof), n, "fused: a vel_dof entry is out of range");
    require(dim(settings, 0) >= diffik::kSettings, "fused: settings must have 7 entries");

    diffik::FusedArgs a;
    a.A = mat(A);
    a.b = vec(b);
    a.w = vec(w);
    a.starts = ivec(starts);
    a.tasks = imat(tasks);
    a.jac = jac.data();
    a.frames = imat(frames);
    a.site_xpos = cmat(site_xpos);
    a.site_xmat = cmat(site_xmat);
    a.xpos = cmat(xpos);
    a.xmat = cmat(xmat);
    a.geom_xpos = cmat(geom_xpos);
    a.geom_xmat = cmat(geom_xmat);
    a.frame_data = cmat(frame_data);
    a.qpos = cvec(qpos);
    a.posture_data = cmat(posture_data);
    a.cfg_dof = ivec(cfg_dof);
    a.cfg_data = cmat(cfg_data);
    a.vel_dof = ivec(vel_dof);
    a.vel_limit = cvec(vel_limit);
    a.settings = cvec(settings);
    return a;
}

}  // namespace

void bind_diffik(nb::module_& m) {
    m.attr("OK") = static_cast<i64>(diffik::OK);
    m.attr("NOT_FINITE") = static_cast<i64>(diffik::NOT_FINITE);
    m.attr("CONFLICT") = static_cast<i64>(diffik::CONFLICT);
    m.attr("UNSETTLED") = static_cast<i64>(diffik::UNSETTLED);

    m.def(
        "boxes",
        [](In1 qpos, double dt, I1 cfg_dof, In1 cfg_lower, In1 cfg_upper, In1 cfg_gain, I1 vel_dof,
           In1 vel_limit, i64 n) {
            require(n >= 0, "boxes: n must be >= 0");
            const i64 E = dim(cfg_dof, 0);
            require(dim(cfg_lower, 0) == E && dim(cfg_upper, 0) == E && dim(cfg_gain, 0) == E,
                    "boxes: cfg_lower, cfg_upper and cfg_gain must have len(cfg_dof) entries");
            require(dim(vel_limit, 0) == dim(vel_dof, 0), "boxes: vel_limit must have len(vel_dof) entries");
            const i64 dofs = std::min(n, dim(qpos, 0));
            check_dofs(ivec(cfg_dof), dofs, "boxes: a cfg_dof entry is out of range");
            check_dofs(ivec(vel_dof), n, "boxes: a vel_dof entry is out of range");
            diffik::Box box = diffik::boxes(cvec(qpos), dt, ivec(cfg_dof), cfg_lower.data(),
                                            cfg_upper.data(), cfg_gain.data(), 1, ivec(vel_dof),
                                            cvec(vel_limit), n);
            return std::make_tuple(to_numpy(std::move(box.lb)), to_numpy(std::move(box.ub)), box.bad);
        },
        nb::arg("qpos"), nb::arg("dt"), nb::arg("cfg_dof"), nb::arg("cfg_lower"), nb::arg("cfg_upper"),
        nb::arg("cfg_gain"), nb::arg("vel_dof"), nb::arg("vel_limit"), nb::arg("n"),
        "The limits' merged box (lb, ub, i): position bounds gain (upper - q), -gain (q - lower), "
        "velocity bounds |dq| <= v_max dt; i >= 0 the first dof whose velocity bounds conflict.");

    m.def(
        "fused_rows",
        [](Out2 A, Out1 b, Out1 w, I1 starts, I2 tasks, In3 jac, I2 frames, In2 site_xpos,
           In2 site_xmat, In2 xpos, In2 xmat, In2 geom_xpos, In2 geom_xmat, In2 frame_data,
           In1 qpos, In2 posture_data, I1 cfg_dof, In2 cfg_data, I1 vel_dof, In1 vel_limit,
           In1 settings) {
            diffik::FusedArgs a = make_args(A, b, w, starts, tasks, jac, frames, site_xpos, site_xmat,
                                            xpos, xmat, geom_xpos, geom_xmat, frame_data, qpos,
                                            posture_data, cfg_dof, cfg_data, vel_dof, vel_limit,
                                            settings);
            diffik::RowsResult r = diffik::fused_rows(a);
            return std::make_tuple(r.code, to_numpy(std::move(r.reg)), to_numpy(std::move(r.box.lb)),
                                   to_numpy(std::move(r.box.ub)));
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("w").noconvert(),
        nb::arg("starts"), nb::arg("tasks"), nb::arg("jac"), nb::arg("frames"), nb::arg("site_xpos"),
        nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"), nb::arg("geom_xpos"),
        nb::arg("geom_xmat"), nb::arg("frame_data"), nb::arg("qpos"), nb::arg("posture_data"),
        nb::arg("cfg_dof"), nb::arg("cfg_data"), nb::arg("vel_dof"), nb::arg("vel_limit"),
        nb::arg("settings"),
        "The hierarchy's rows and limits without solving it: fills A, b, w and returns (code, "
        "reg, lb, ub); see qpik._fused.fused_step for the arguments.");

    m.def(
        "fused_step",
        [](Out2 A, Out1 b, Out1 w, I1 starts, I2 tasks, In3 jac, I2 frames, In2 site_xpos,
           In2 site_xmat, In2 xpos, In2 xmat, In2 geom_xpos, In2 geom_xmat, In2 frame_data,
           In1 qpos, In2 posture_data, I1 cfg_dof, In2 cfg_data, I1 vel_dof, In1 vel_limit,
           In1 settings, i64 max_iter, B2 warm, bool canonical) {
            diffik::FusedArgs a = make_args(A, b, w, starts, tasks, jac, frames, site_xpos, site_xmat,
                                            xpos, xmat, geom_xpos, geom_xmat, frame_data, qpos,
                                            posture_data, cfg_dof, cfg_data, vel_dof, vel_limit,
                                            settings);
            const i64 n = a.qpos.n, L = a.starts.n - 1;
            require(dim(warm, 0) == L && dim(warm, 1) == n, "fused_step: warm must have shape (L, nv)");
            diffik::StepResult r = diffik::fused_step(
                a, max_iter, MatRefT<const i8>(warm.data(), L, n), canonical);
            if (r.v_is_d) r.v = r.d;
            const size_t L_ = static_cast<size_t>(L), cols = static_cast<size_t>(r.active_cols);
            return std::make_tuple(r.code, to_numpy(std::move(r.d)), to_numpy(std::move(r.v)),
                                   to_numpy(std::move(r.info), {9, L_}),
                                   to_numpy(std::move(r.active), {L_, cols}));
        },
        nb::arg("A").noconvert(), nb::arg("b").noconvert(), nb::arg("w").noconvert(),
        nb::arg("starts"), nb::arg("tasks"), nb::arg("jac"), nb::arg("frames"), nb::arg("site_xpos"),
        nb::arg("site_xmat"), nb::arg("xpos"), nb::arg("xmat"), nb::arg("geom_xpos"),
        nb::arg("geom_xmat"), nb::arg("frame_data"), nb::arg("qpos"), nb::arg("posture_data"),
        nb::arg("cfg_dof"), nb::arg("cfg_data"), nb::arg("vel_dof"), nb::arg("vel_limit"),
        nb::arg("settings"), nb::arg("max_iter"), nb::arg("warm"), nb::arg("canonical"),
        "Rows of every task, the limits' box and the cascade in one call; returns (code, dq, v, "
        "info (9, L), active (L, nv) int8). See qpik._fused.fused_step.");
}

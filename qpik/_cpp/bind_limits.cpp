// Bindings of the limits layer (qpik._engine.limits): the conservative culling of collision
// pairs and the pairs' contact normal rows (limits/collision.hpp), used by
// qpik.limits.collision; the support polygon's edges (limits/support.hpp), used by
// qpik.limits.support. Every shape and geom id is
// checked here, so a bad argument raises ValueError instead of reading out of bounds.
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <nanobind/stl/pair.h>
#include <nanobind/stl/vector.h>

#include "bind.hpp"
#include "limits/collision.hpp"
#include "limits/support.hpp"

namespace nb = nanobind;
using namespace qpik;
using namespace qpik::bind;

void bind_limits(nb::module_& m) {
    m.def(
        "free_joint_rows",
        [](In1 xmat, In<i64, 1> lin_dofs, i64 nv, double dt, In1 linear_max) {
            require(xmat.shape(0) == 9, "free_joint_rows: xmat must be (9,)");
            require(lin_dofs.shape(0) == 3 && linear_max.shape(0) == 3,
                    "free_joint_rows: lin_dofs and linear_max must be (3,)");
            require(nv >= 0, "free_joint_rows: nv must be >= 0");
            for (size_t j = 0; j < 3; ++j)
                require(lin_dofs.data()[j] >= 0 && lin_dofs.data()[j] < nv, "free_joint_rows: a dof is out of range");
            std::vector<double> G(static_cast<size_t>(6 * nv), 0.0), h(6);
            const double* x = xmat.data();  // R row-major: row r of R^T is column r of R
            for (i64 r = 0; r < 3; ++r) {
                double* up = G.data() + r * nv;
                for (i64 j = 0; j < 3; ++j) up[lin_dofs.data()[j]] = x[3 * j + r];
                double* down = G.data() + (3 + r) * nv;
                for (i64 k = 0; k < nv; ++k) down[k] = -up[k];
                h[static_cast<size_t>(r)] = h[static_cast<size_t>(3 + r)] = dt * linear_max.data()[r];
            }
            return std::make_pair(to_numpy(std::move(G), {6, static_cast<size_t>(nv)}), to_numpy(std::move(h)));
        },
        nb::arg("xmat"), nb::arg("lin_dofs"), nb::arg("nv"), nb::arg("dt"), nb::arg("linear_max"),
        "mink's FreeJointVelocityLimit's linear rows G dq <= h, bitwise as it computes them: R^T\n"
        "(R the base's xmat (9,), row-major) on the three linear dofs, then its negation (every\n"
        "entry, zeros to -0); h = dt linear_max, twice. G (6, nv), h (6,).");
    m.def(
        "row_stats",
        [](In2 G, In1 h, double tol) {
            const i64 rows = static_cast<i64>(G.shape(0)), n = static_cast<i64>(G.shape(1));
            const i64 p = static_cast<i64>(h.shape(0));
            i64 bad_g = 0, bad_h = 0, fewest = n, negligible = 0;
            for (i64 r = 0; r < rows; ++r) {
                const double* g = G.data() + r * n;
                i64 nonzero = 0;
                double largest = 0.0;
                for (i64 j = 0; j < n; ++j) {
                    bad_g += !std::isfinite(g[j]);
                    nonzero += g[j] != 0.0;
                    largest = limits::numpy_max_abs(largest, g[j]);
                }
                fewest = std::min(fewest, nonzero);
                negligible += largest > 0.0 && largest <= tol;
            }
            for (i64 i = 0; i < p; ++i) bad_h += !(h.data()[i] > -kInf);
            return std::make_tuple(bad_g, bad_h, fewest, negligible);
        },
        nb::arg("G"), nb::arg("h"), nb::arg("tol"),
        "A limit's rows G dq <= h (p, n) as qpik.diffik takes them, counted without NumPy's\n"
        "temporaries: the entries of G that are not finite and those of h that are NaN or -inf\n"
        "(NumPy's isfinite and h > -inf), the fewest nonzero entries of a row (n where p = 0), and\n"
        "the negligible rows, whose largest |entry| is in (0, tol] (a NaN entry makes its row's\n"
        "largest NaN: NumPy's max).");
    m.def(
        "collision_candidates",
        [](In<i64, 2> pairs, In<std::int32_t, 1> geom_type, In2 geom_size, In2 geom_aabb, In1 geom_rbound, In2 geom_xpos,
           In2 geom_xmat, double threshold, Out<i64, 1> out) {
            const size_t ngeom = geom_type.shape(0);
            require(geom_size.shape(0) == ngeom && geom_size.shape(1) == 3, "geom_size must be (ngeom, 3)");
            require(geom_aabb.shape(0) == ngeom && geom_aabb.shape(1) == 6, "geom_aabb must be (ngeom, 6)");
            require(geom_rbound.shape(0) == ngeom, "geom_rbound must be (ngeom,)");
            require(geom_xpos.shape(0) == ngeom && geom_xpos.shape(1) == 3, "geom_xpos must be (ngeom, 3)");
            require(geom_xmat.shape(0) == ngeom && geom_xmat.shape(1) == 9, "geom_xmat must be (ngeom, 9)");
            const i64 P = static_cast<i64>(pairs.shape(0));
            require(P == 0 || pairs.shape(1) == 2, "pairs must be (P, 2) geom ids");
            require(static_cast<i64>(out.shape(0)) >= P, "out must hold at least P entries");
            const i64* ids = pairs.data();
            for (i64 k = 0; k < 2 * P; ++k)
                require(ids[k] >= 0 && ids[k] < static_cast<i64>(ngeom), "pairs: a geom id is out of range");
            nb::gil_scoped_release release;
            return limits::collision_candidates(ids, P, static_cast<i64>(ngeom), geom_type.data(),
                                                geom_size.data(), geom_aabb.data(), geom_rbound.data(),
                                                geom_xpos.data(), geom_xmat.data(), threshold, out.data());
        },
        nb::arg("pairs"), nb::arg("geom_type"), nb::arg("geom_size"), nb::arg("geom_aabb"), nb::arg("geom_rbound"),
        nb::arg("geom_xpos"),
        nb::arg("geom_xmat"), nb::arg("threshold"), nb::arg("out").noconvert(),
        "Indices of the geom pairs (P, 2) whose distance may be at most threshold [m] (a\n"
        "conservative lower bound from each geom's bounding sphere, capsule, box or half-space,\n"
        "MuJoCo's geom_type / geom_size / geom_aabb / geom_rbound at geom_xpos / geom_xmat), in order, written\n"
        "into out (P,) int64; returns how many.");
    m.def(
        "contact_normal_rows",
        [](In2 cdof, In2 subtree_com, In<i64, 1> starts, In<i64, 1> dofs, In<i64, 1> roots,
           const std::vector<i64>& which, In2 fromto, const std::vector<double>& dist, double gain, double d_min,
           double relaxation, double dt, bool velocity) {
            const i64 n = static_cast<i64>(cdof.shape(0));
            const i64 nbody = static_cast<i64>(subtree_com.shape(0));
            const i64 C = static_cast<i64>(roots.shape(0));
            const i64 k = static_cast<i64>(which.size());
            require(cdof.shape(1) == 6, "contact_normal_rows: cdof must be (nv, 6)");
            require(subtree_com.shape(1) == 3, "contact_normal_rows: subtree_com must be (nbody, 3)");
            require(C % 2 == 0 && static_cast<i64>(starts.shape(0)) == C + 1,
                    "contact_normal_rows: roots must be (2P,) and starts (2P + 1,)");
            const i64* st = starts.data();
            const i64 D = static_cast<i64>(dofs.shape(0));
            require(C == 0 || (st[0] == 0 && st[C] == D), "contact_normal_rows: starts must run from 0 to len(dofs)");
            for (i64 c = 0; c < C; ++c) {
                require(st[c] <= st[c + 1], "contact_normal_rows: starts must not decrease");
                require(roots.data()[c] >= 0 && roots.data()[c] < nbody, "contact_normal_rows: a root is out of range");
            }
            for (i64 e = 0; e < D; ++e)
                require(dofs.data()[e] >= 0 && dofs.data()[e] < n, "contact_normal_rows: a dof is out of range");
            for (i64 r = 0; r < k; ++r)
                require(which[r] >= 0 && which[r] < C / 2, "contact_normal_rows: a pair is out of range");
            require(fromto.shape(0) >= static_cast<size_t>(k) && fromto.shape(1) == 6,
                    "contact_normal_rows: fromto must be (k, 6)");
            require(dist.size() >= static_cast<size_t>(k), "contact_normal_rows: dist must hold k entries");
            std::vector<double> jac(static_cast<size_t>(6 * n)), G(static_cast<size_t>(k * n)),
                h(static_cast<size_t>(k));
            const i64 fewest = limits::contact_normal_rows(cdof.data(), subtree_com.data(), n, st, dofs.data(),
                                                           roots.data(), which.data(), fromto.data(), dist.data(), k,
                                                           gain, d_min, relaxation, dt, velocity, jac.data(),
                                                           G.data(), h.data());
            return std::make_tuple(to_numpy(std::move(G), {static_cast<size_t>(k), static_cast<size_t>(n)}),
                                   to_numpy(std::move(h)), fewest);
        },
        nb::arg("cdof"), nb::arg("subtree_com"), nb::arg("starts"), nb::arg("dofs"), nb::arg("roots"),
        nb::arg("which"), nb::arg("fromto"), nb::arg("dist"), nb::arg("gain"), nb::arg("d_min"),
        nb::arg("relaxation"), nb::arg("dt"), nb::arg("velocity"),
        "The contact normal rows G (k, nv) of geom pairs, as mink's\n"
        "compute_contact_normal_jacobian makes them and its limits sign them: row r of pair\n"
        "which[r] (chains 2p, 2p + 1 of starts / dofs / roots: geom 1's body, geom 2's; qpik.model.frames.\n"
        "frame_chains), mj_geomDistance's dist[r] and fromto[r]: sign n^T (J2 - J1), n the unit\n"
        "normal from geom 1's point to geom 2's, J1 and J2 mj_jac at those points from the MjData's\n"
        "cdof and subtree_com, sign -1 where dist >= 0, else +1. The right sides h (k,):\n"
        "velocity (mink's): gain (d - d_min) / dt + relaxation where d > d_min, else relaxation;\n"
        "else gain (d - d_min) + relaxation [m]. Returns (G, h, the fewest nonzero entries of a\n"
        "row: nv where k = 0); which (k,) and dist (k,) are sequences (lists).");
    m.def(
        "support_hull",
        [](In2 points) {
            const size_t n = points.shape(0);
            require(n == 0 || points.shape(1) == 2, "support_hull: points must be (n, 2)");
            std::vector<double> normals(2 * n), offsets(n);
            const i64 e = limits::support_hull(points.data(), static_cast<i64>(n), normals.data(), offsets.data());
            normals.resize(static_cast<size_t>(2 * e));
            offsets.resize(static_cast<size_t>(e));
            return std::make_pair(to_numpy(std::move(normals), {static_cast<size_t>(e), 2}),
                                  to_numpy(std::move(offsets)));
        },
        nb::arg("points"),
        "The convex hull of ground points (n, 2) [m], world x-y: its edges' outward unit normals\n"
        "(e, 2) and offsets (e,) (inside: normals @ p + offsets <= 0), counter-clockwise from the\n"
        "lowest-x point; e = 0 where the points span no area or one is not finite.");
    // The footprints of support_points / support_rows: frames (F, 3) and (F, 9), one (k_f, 3)
    // array a frame; the points' count.
    auto check_frames = [](const In2& positions, const In2& rotations, const std::vector<In2>& footprints) {
        const size_t F = positions.shape(0);
        require(positions.shape(1) == 3, "support: positions must be (F, 3)");
        require(rotations.shape(0) == F && rotations.shape(1) == 9, "support: rotations must be (F, 9)");
        require(footprints.size() == F, "support: one footprint a frame");
        i64 n = 0;
        for (const In2& fp : footprints) {
            require(fp.shape(0) == 0 || fp.shape(1) == 3, "support: a footprint must be (k, 3)");
            const size_t k = fp.shape(0) * fp.shape(1);
            for (size_t i = 0; i < k; ++i) require(std::isfinite(fp.data()[i]), "support: a footprint is not finite");
            n += static_cast<i64>(fp.shape(0));
        }
        return n;
    };
    auto points_of = [](const In2& positions, const In2& rotations, const std::vector<In2>& footprints,
                        std::vector<double>& out) {
        const size_t F = footprints.size();
        std::vector<const double*> fps(F);
        std::vector<i64> counts(F);
        for (size_t f = 0; f < F; ++f) {
            fps[f] = footprints[f].data();
            counts[f] = static_cast<i64>(footprints[f].shape(0));
        }
        limits::support_points(positions.data(), rotations.data(), static_cast<i64>(F), fps.data(), counts.data(),
                               out.data());
    };
    m.def(
        "support_points",
        [check_frames, points_of](In2 positions, In2 rotations, std::vector<In2> footprints) {
            const i64 n = check_frames(positions, rotations, footprints);
            std::vector<double> out(static_cast<size_t>(2 * n));
            points_of(positions, rotations, footprints, out);
            return to_numpy(std::move(out), {static_cast<size_t>(n), 2});
        },
        nb::arg("positions"), nb::arg("rotations"), nb::arg("footprints"),
        "The footprints' points on the ground (n, 2) [m], world x-y: frame f at positions[f] (3,)\n"
        "with rotations[f] (9,) (row-major, local to world) carries footprints[f] (k_f, 3) [m] in\n"
        "its own axes, each landing at p_f + R_f x; frame by frame.");
    m.def(
        "support_rows",
        [check_frames, points_of](In2 positions, In2 rotations, std::vector<In2> footprints, In2 jac, double com_x,
                                  double com_y, double margin, double gain, double negligible) {
            const i64 n = check_frames(positions, rotations, footprints);
            require(jac.shape(0) >= 2, "support_rows: jac must hold the CoM Jacobian's x and y rows (>= 2, nv)");
            const i64 nv = static_cast<i64>(jac.shape(1));
            std::vector<double> pts(static_cast<size_t>(2 * n));
            points_of(positions, rotations, footprints, pts);
            // (the hull first: G and h sized by its edges, not by the points)
            std::vector<double> normals(static_cast<size_t>(2 * n)), offsets(static_cast<size_t>(n));
            const i64 e = limits::support_hull(pts.data(), n, normals.data(), offsets.data());
            std::vector<double> G(static_cast<size_t>(e * nv)), h(static_cast<size_t>(e));
            i64 fewest = nv;
            limits::support_rows(normals.data(), offsets.data(), e, jac.data(), jac.data() + nv, nv, com_x, com_y,
                                 margin, gain, G.data(), h.data(), fewest, negligible);
            return std::make_tuple(to_numpy(std::move(G), {static_cast<size_t>(e), static_cast<size_t>(nv)}),
                                   to_numpy(std::move(h)), fewest);
        },
        nb::arg("positions"), nb::arg("rotations"), nb::arg("footprints"), nb::arg("jac"), nb::arg("com_x"),
        nb::arg("com_y"), nb::arg("margin"), nb::arg("gain"), nb::arg("negligible") = 0.0,
        "The support polygon's rows G dq <= h [m] (qpik.limits.SupportPolygonLimit): the hull\n"
        "(support_hull) of the footprints' ground points (support_points), and per edge a\n"
        "G_e = a_e^T J_xy (jac's first two rows: the CoM Jacobian's x and y), h_e = gain (-margin -\n"
        "o_e - a_e^T c_xy); (G (e, nv), h (e,), the fewest nonzero entries of a row), e = 0 where\n"
        "the points span no area. A row whose entries are all at most `negligible` in size is made\n"
        "zero (qpik.limits.collision.NEGLIGIBLE_ROW; 0: none).");
}

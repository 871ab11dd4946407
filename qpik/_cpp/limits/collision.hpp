// Conservative culling of collision pairs: a lower bound on the distance between two geoms
// from their placement and size alone (no contact routine), so that only the pairs that may
// lie within the detection distance are handed to MuJoCo's mj_geomDistance.
//
// Each geom is bounded by a simple convex shape that contains the body MuJoCo's colliders
// use: a sphere (spheres), a capsule (capsules, and cylinders: a cylinder lies inside the
// capsule of the same radius and half-length), an oriented box (boxes, ellipsoids inside
// their box, meshes inside their axis-aligned box in the geom frame, MuJoCo's geom_aabb),
// or a half-space (planes: MuJoCo's plane colliders treat a plane as infinite). Height
// fields and other types are never culled. Between two shapes the bound is
//   sphere/capsule - sphere/capsule: the exact distance of their segments minus the radii;
//   box - sphere: the exact distance of the centre to the box minus the radius;
//   box - capsule, box - box: the largest gap between the shapes' projections on the
//     separating-axis candidates (face normals, cross products of edge directions);
//   half-space - shape: the shape's lowest point along the normal above the plane.
// Every bound is at most the true distance (a gap along any unit axis is), so a pair whose
// bound exceeds the threshold is provably farther apart than it.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "../common.hpp"
#include "../model/jac.hpp"

namespace qpik::limits {

// MuJoCo's mjtGeom codes.
enum GeomType : int { kPlane = 0, kHfield = 1, kSphere = 2, kCapsule = 3, kEllipsoid = 4,
                      kCylinder = 5, kBox = 6, kMesh = 7 };

// The bounding shape of one geom, in world coordinates.
struct Shape {
    enum Kind { kNever, kHalfSpace, kSegment, kBox } kind = kNever;
    double c[3] = {0, 0, 0};       // centre (segment midpoint, box centre, point on the plane)
    double axis[3][3] = {};        // box: its axes (world); segment / plane: axis[0] the direction / normal
    double half[3] = {0, 0, 0};    // box: half sizes; segment: half[0] its half-length
    double radius = 0.0;           // segment: the radius around it (0 for a box)
};

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The shape of geom ``type`` with ``size`` (3,), ``aabb`` (6: centre, half sizes in the geom
// frame), placed at ``xpos`` (3,) with orientation ``xmat`` (9, row-major: world = R local).
inline Shape shape_of(int type, const double* size, const double* aabb, const double* xpos,
                      const double* xmat) {
    Shape s;
    auto column = [&](int j, double* out) {
        out[0] = xmat[j];
        out[1] = xmat[3 + j];
        out[2] = xmat[6 + j];
    };
    for (int i = 0; i < 3; ++i) s.c[i] = xpos[i];
    switch (type) {
        case kPlane:
            s.kind = Shape::kHalfSpace;
            column(2, s.axis[0]);
            break;
        case kSphere:
            s.kind = Shape::kSegment;
            column(2, s.axis[0]);
            s.radius = size[0];
            break;
        case kCapsule:
        case kCylinder:
            s.kind = Shape::kSegment;
            column(2, s.axis[0]);
            s.radius = size[0];
            s.half[0] = size[1];
            break;
        case kBox:
        case kEllipsoid:
            s.kind = Shape::kBox;
            for (int j = 0; j < 3; ++j) {
                column(j, s.axis[j]);
                s.half[j] = size[j];
            }
            break;
        case kMesh:
            s.kind = Shape::kBox;
            for (int j = 0; j < 3; ++j) {
                column(j, s.axis[j]);
                s.half[j] = aabb[3 + j];
            }
            for (int i = 0; i < 3; ++i)
                s.c[i] = xpos[i] + xmat[3 * i] * aabb[0] + xmat[3 * i + 1] * aabb[1] + xmat[3 * i + 2] * aabb[2];
            break;
        default:
            s.kind = Shape::kNever;
    }
    return s;
}

// The interval [lo, hi] of a segment or box's projection on the unit axis ``u``.
inline void project(const Shape& s, const double* u, double& lo, double& hi) {
    double centre = dot3(s.c, u);
    double extent = 0.0;
    if (s.kind == Shape::kSegment) {
        extent = std::fabs(dot3(s.axis[0], u)) * s.half[0] + s.radius;
    } else {
        for (int j = 0; j < 3; ++j) extent += std::fabs(dot3(s.axis[j], u)) * s.half[j];
    }
    lo = centre - extent;
    hi = centre + extent;
}

// The gap between the projections of ``a`` and ``b`` on the axis ``u`` (normalised here;
// -inf for a degenerate axis): a lower bound on their distance.
inline double gap_along(const Shape& a, const Shape& b, const double* axis) {
    double n = std::sqrt(dot3(axis, axis));
    if (!(n > 1e-12)) return -kInf;
    double u[3] = {axis[0] / n, axis[1] / n, axis[2] / n};
    double alo, ahi, blo, bhi;
    project(a, u, alo, ahi);
    project(b, u, blo, bhi);
    return std::max(blo - ahi, alo - bhi);
}

inline void cross3(const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

// The distance between segments [p0, p1] and [q0, q1] (Ericson, Real-Time Collision
// Detection, 5.1.9).
inline double segment_distance(const double* p0, const double* p1, const double* q0, const double* q1) {
    double d1[3], d2[3], r[3];
    for (int i = 0; i < 3; ++i) {
        d1[i] = p1[i] - p0[i];
        d2[i] = q1[i] - q0[i];
        r[i] = p0[i] - q0[i];
    }
    double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r);
    double s = 0.0, t = 0.0;
    const double eps = 1e-300;
    if (a <= eps && e <= eps) {
        s = t = 0.0;
    } else if (a <= eps) {
        t = std::clamp(f / e, 0.0, 1.0);
    } else {
        double c = dot3(d1, r);
        if (e <= eps) {
            s = std::clamp(-c / a, 0.0, 1.0);
        } else {
            double b = dot3(d1, d2);
            double denom = a * e - b * b;
            s = denom > 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = std::clamp(-c / a, 0.0, 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = std::clamp((b - c) / a, 0.0, 1.0);
            }
        }
    }
    double d[3];
    for (int i = 0; i < 3; ++i) d[i] = (p0[i] + d1[i] * s) - (q0[i] + d2[i] * t);
    return std::sqrt(dot3(d, d));
}

inline void endpoints(const Shape& s, double* p0, double* p1) {
    for (int i = 0; i < 3; ++i) {
        p0[i] = s.c[i] - s.axis[0][i] * s.half[0];
        p1[i] = s.c[i] + s.axis[0][i] * s.half[0];
    }
}

// A lower bound on the distance between shapes ``a`` and ``b`` [m] (-inf: none known).
inline double distance_lower_bound(const Shape& a, const Shape& b) {
    if (a.kind == Shape::kNever || b.kind == Shape::kNever) return -kInf;
    if (a.kind == Shape::kHalfSpace || b.kind == Shape::kHalfSpace) {
        if (a.kind == b.kind) return -kInf;
        const Shape& plane = a.kind == Shape::kHalfSpace ? a : b;
        const Shape& other = a.kind == Shape::kHalfSpace ? b : a;
        double lo, hi;
        project(other, plane.axis[0], lo, hi);
        return lo - dot3(plane.c, plane.axis[0]);
    }
    if (a.kind == Shape::kSegment && b.kind == Shape::kSegment) {
        double p0[3], p1[3], q0[3], q1[3];
        endpoints(a, p0, p1);
        endpoints(b, q0, q1);
        return segment_distance(p0, p1, q0, q1) - a.radius - b.radius;
    }
    if (a.kind == Shape::kBox && b.kind == Shape::kBox) {
        double best = -kInf, axis[3];
        for (int i = 0; i < 3; ++i) {
            best = std::max(best, gap_along(a, b, a.axis[i]));
            best = std::max(best, gap_along(a, b, b.axis[i]));
            for (int j = 0; j < 3; ++j) {
                cross3(a.axis[i], b.axis[j], axis);
                best = std::max(best, gap_along(a, b, axis));
            }
        }
        return best;
    }
    const Shape& box = a.kind == Shape::kBox ? a : b;
    const Shape& seg = a.kind == Shape::kBox ? b : a;
    if (seg.half[0] == 0.0) {  // a sphere: the exact distance of its centre to the box
        double sq = 0.0;
        for (int j = 0; j < 3; ++j) {
            double r[3] = {seg.c[0] - box.c[0], seg.c[1] - box.c[1], seg.c[2] - box.c[2]};
            double x = dot3(r, box.axis[j]);
            double out = std::fabs(x) - box.half[j];
            if (out > 0.0) sq += out * out;
        }
        if (!(sq > 0.0)) return -kInf;  // the centre inside: the depth is not bounded here
        return std::sqrt(sq) - seg.radius;
    }
    double best = -kInf, axis[3];
    for (int j = 0; j < 3; ++j) {
        best = std::max(best, gap_along(box, seg, box.axis[j]));
        cross3(seg.axis[0], box.axis[j], axis);
        best = std::max(best, gap_along(box, seg, axis));
    }
    return best;
}

// The indices of the pairs ``pairs`` (P, 2: geom ids) whose distance may be at most
// ``threshold`` [m], in order, written into ``out`` (P,); returns how many. A pair of geoms
// with bounding spheres (``geom_rbound`` > 0, about ``geom_xpos``) farther apart than the
// threshold is dropped first (mink's broadphase test), then by its shapes' bound.
inline i64 collision_candidates(const i64* pairs, i64 P, i64 ngeom, const int* geom_type,
                                const double* geom_size, const double* geom_aabb,
                                const double* geom_rbound, const double* geom_xpos,
                                const double* geom_xmat, double threshold, i64* out) {
    std::vector<Shape> shapes(static_cast<size_t>(ngeom));
    std::vector<char> built(static_cast<size_t>(ngeom), 0);
    auto shape = [&](i64 g) -> const Shape& {
        if (!built[g]) {
            shapes[g] = shape_of(geom_type[g], geom_size + 3 * g, geom_aabb + 6 * g, geom_xpos + 3 * g,
                                 geom_xmat + 9 * g);
            built[g] = 1;
        }
        return shapes[g];
    };
    i64 n = 0;
    for (i64 k = 0; k < P; ++k) {
        i64 g1 = pairs[2 * k], g2 = pairs[2 * k + 1];
        double r1 = geom_rbound[g1], r2 = geom_rbound[g2];
        if (r1 > 0.0 && r2 > 0.0) {
            const double* p = geom_xpos + 3 * g1;
            const double* q = geom_xpos + 3 * g2;
            double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
            double reach = r1 + r2 + threshold;
            if (reach >= 0.0 && dot3(d, d) > reach * reach) continue;
        }
        double bound = distance_lower_bound(shape(g1), shape(g2));
        if (!(bound > threshold)) out[n++] = k;  // NaN: kept
    }
    return n;
}

// The contact normal rows of geom pairs, as mink's compute_contact_normal_jacobian makes them
// (mink/limits/collision_avoidance_limit.py) and its collision limits sign them: per row r, the
// pair p = which[r] with mj_geomDistance's dist[r] and fromto[r] (6: the point on geom 1, then
// on geom 2), the unit normal n = (to - from) / |to - from| (MuJoCo's mju_normalize3: (1, 0, 0)
// below mjMINVAL), the point Jacobians J1 at `from` on geom 1's body and J2 at `to` on geom 2's
// (mj_jac, model/jac.hpp: chains 2p and 2p + 1 of starts / dofs / roots), and
// G[r] = sign n^T (J2 - J1), sign -1 where dist >= 0, else +1. The right sides h[r] as the
// limits compute them: `velocity` (mink's): gain (d - d_min) / dt + relaxation where
// d > d_min, else relaxation; else (qpik's, a displacement): gain (d - d_min) + relaxation.
// cdof (nv, 6) and subtree_com (nbody, 3) are the MjData's; jac (2, 3, nv) scratch. Returns
// the fewest nonzero entries of a row (n where k = 0). Every index is checked by the caller.
inline i64 contact_normal_rows(const double* cdof, const double* subtree_com, i64 n, const i64* starts,
                               const i64* dofs, const i64* roots, const i64* which, const double* fromto,
                               const double* dist, i64 k, double gain, double d_min, double relaxation,
                               double dt, bool velocity, double* jac, double* G, double* h) {
    i64 fewest = n;
    constexpr double kMinVal = 1e-15;  // MuJoCo's mjMINVAL
    double* j1 = jac;
    double* j2 = jac + 3 * n;
    for (i64 r = 0; r < k; ++r) {
        const i64 c1 = 2 * which[r], c2 = c1 + 1;
        const double* from = fromto + 6 * r;
        const double* to = from + 3;
        double normal[3] = {to[0] - from[0], to[1] - from[1], to[2] - from[2]};
        const double norm = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
        if (norm < kMinVal) {
            normal[0] = 1.0;
            normal[1] = normal[2] = 0.0;
        } else {
            const double inv = 1.0 / norm;
            for (double& x : normal) x *= inv;
        }
        std::fill(jac, jac + 6 * n, 0.0);
        model::chain_point_jacobian(cdof, n, dofs + starts[c2], starts[c2 + 1] - starts[c2], to,
                                    subtree_com + 3 * roots[c2], j2, nullptr);
        model::chain_point_jacobian(cdof, n, dofs + starts[c1], starts[c1 + 1] - starts[c1], from,
                                    subtree_com + 3 * roots[c1], j1, nullptr);
        const double d = dist[r];
        const double sign = d >= 0.0 ? -1.0 : 1.0;
        double* g = G + r * n;
        i64 nonzero = 0;
        for (i64 j = 0; j < n; ++j) {
            const double d0 = j2[j] - j1[j], d1 = j2[n + j] - j1[n + j], d2 = j2[2 * n + j] - j1[2 * n + j];
            g[j] = sign * (normal[0] * d0 + normal[1] * d1 + normal[2] * d2);
            nonzero += g[j] != 0.0;
        }
        fewest = std::min(fewest, nonzero);
        if (velocity) h[r] = d > d_min ? (gain * (d - d_min) / dt) + relaxation : relaxation;
        else h[r] = gain * (d - d_min) + relaxation;
    }
    return fewest;
}

}  // namespace qpik::limits

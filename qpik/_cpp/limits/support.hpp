// The support polygon's edges: the convex hull of a few ground points (x, y) [m] by Andrew's
// monotone chain, for qpik.limits.SupportPolygonLimit. A humanoid's two soles make eight
// points; scipy's Qhull spends about 90 us on its set-up for them, this about 1 us.
//
// The hull runs counter-clockwise from the lowest-x point (the lowest y among equal x). A
// point is dropped from the chain where the chain goes on through it turning by less than
// kTurn (the sine of the angle its two edges make): collinear and repeated points, and
// points off the line by round-off, which would otherwise make edges of round-off length
// whose normals are round-off; such a point lies at most kTurn times an edge's length out. Each
// edge's outward unit normal n and offset o (inside: n . p + o <= 0) are computed from its
// two end points alone, o = -(n . a + n . b) / 2. Points that span no area (fewer than three
// hull vertices, or an area under kTurn times the squared extent) give no polygon.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "../common.hpp"

namespace qpik::limits {

inline constexpr double kTurn = 1e-10;

// The hull of the n points pts (n, 2) row-major: its edge count e (at most n) with the edges'
// normals (e, 2) and offsets (e,) written into normals / offsets (n rows / entries each);
// 0 (nothing written) where the points span no area or one is not finite.
inline i64 support_hull(const double* pts, i64 n, double* normals, double* offsets) {
    struct Point {
        double x, y;
        i64 index;
    };
    // The chain's tests on the points scaled by a power of two (exact) to at most 1 in size:
    // their squares neither overflow nor depend on the unit.
    double big = 0.0;
    for (i64 i = 0; i < 2 * n; ++i) {
        if (!std::isfinite(pts[i])) return 0;
        big = std::max(big, std::fabs(pts[i]));
    }
    if (n < 3 || !(big > 0.0)) return 0;
    int exponent = 0;
    std::frexp(big, &exponent);
    const double unit = std::ldexp(1.0, -exponent);
    std::vector<Point> sorted(static_cast<size_t>(n));
    double lo[2] = {kInf, kInf}, hi[2] = {-kInf, -kInf};
    for (i64 i = 0; i < n; ++i) {
        const double x = pts[2 * i] * unit, y = pts[2 * i + 1] * unit;
        sorted[static_cast<size_t>(i)] = Point{x, y, i};
        lo[0] = std::min(lo[0], x);
        hi[0] = std::max(hi[0], x);
        lo[1] = std::min(lo[1], y);
        hi[1] = std::max(hi[1], y);
    }
    // (x, then y, then the index: a total order, the same sort on every machine)
    std::sort(sorted.begin(), sorted.end(), [](const Point& a, const Point& b) {
        if (a.x != b.x) return a.x < b.x;
        if (a.y != b.y) return a.y < b.y;
        return a.index < b.index;
    });
    // o -> a -> b turns left: going on (its two edges' dot product positive), by more than
    // kTurn (the sine of the turn: cross^2 > kTurn^2 |a - o|^2 |b - a|^2, no square root);
    // going back (the chain reverses along a line of nearly equal x, its points sorted by
    // round-off in x), by the cross product's sign alone. There the x differences ax, bx are
    // >= 0 and ay, by have opposite signs (or one is 0), so the two terms of the cross
    // product have the same sign: it is exact in sign, and keeps the lowest (the upper
    // chain: highest) of such points.
    auto left = [](const Point& o, const Point& a, const Point& b) {
        const double ax = a.x - o.x, ay = a.y - o.y;
        const double bx = b.x - a.x, by = b.y - a.y;
        const double cross = ax * by - ay * bx;
        if (ax * bx + ay * by <= 0.0) return cross > 0.0;
        return cross > 0.0 && cross * cross > (kTurn * kTurn) * ((ax * ax + ay * ay) * (bx * bx + by * by));
    };
    // The lower chain left to right, then the upper one back (its turns tested on its own
    // points: from the rightmost on); the last point, the first again, dropped.
    std::vector<Point> chain(static_cast<size_t>(2 * n));
    size_t top = 0;
    for (i64 s = 0; s < n; ++s) {
        const Point& p = sorted[static_cast<size_t>(s)];
        while (top >= 2 && !left(chain[top - 2], chain[top - 1], p)) --top;
        chain[top++] = p;
    }
    const size_t upper = top + 1;
    for (i64 s = n - 2; s >= 0; --s) {
        const Point& p = sorted[static_cast<size_t>(s)];
        while (top >= upper && !left(chain[top - 2], chain[top - 1], p)) --top;
        chain[top++] = p;
    }
    const i64 e = static_cast<i64>(top) - 1;
    if (e < 3) return 0;
    double area = 0.0;  // twice the area (shoelace about the first vertex, scaled points)
    for (i64 k = 1; k + 1 < e; ++k) {
        const Point &a = chain[static_cast<size_t>(k)], &b = chain[static_cast<size_t>(k + 1)];
        area += (a.x - chain[0].x) * (b.y - chain[0].y) - (b.x - chain[0].x) * (a.y - chain[0].y);
    }
    const double extent = std::max(hi[0] - lo[0], hi[1] - lo[1]);
    if (!(area > 2.0 * kTurn * extent * extent)) return 0;
    for (i64 k = 0; k < e; ++k) {
        const i64 a = chain[static_cast<size_t>(k)].index, b = chain[static_cast<size_t>((k + 1) % e)].index;
        const double dx = pts[2 * b] - pts[2 * a], dy = pts[2 * b + 1] - pts[2 * a + 1];
        const double len = std::hypot(dx, dy);
        const double nx = dy / len, ny = -dx / len;  // outward: the interior is on the left
        normals[2 * k] = nx;
        normals[2 * k + 1] = ny;
        offsets[k] = -((nx * pts[2 * a] + ny * pts[2 * a + 1]) + (nx * pts[2 * b] + ny * pts[2 * b + 1])) / 2.0;
    }
    return e;
}

// The footprints' points on the ground (x, y) [m], world: frame f at position pos (F, 3) with
// rotation rot (F, 9, row-major, local to world) carries counts[f] points fps[f] (k, 3) in
// its own axes; point k of it lands at pos_f + R_f p_k, of which x and y are written into
// out (sum counts, 2), frame by frame.
inline void support_points(const double* pos, const double* rot, i64 F, const double* const* fps,
                           const i64* counts, double* out) {
    for (i64 f = 0; f < F; ++f) {
        const double* R = rot + 9 * f;
        const double px = pos[3 * f], py = pos[3 * f + 1];
        const double* fp = fps[f];
        for (i64 k = 0; k < counts[f]; ++k, fp += 3, out += 2) {
            out[0] = px + ((R[0] * fp[0] + R[1] * fp[1]) + R[2] * fp[2]);
            out[1] = py + ((R[3] * fp[0] + R[4] * fp[1]) + R[5] * fp[2]);
        }
    }
}

// Below this fraction of the size of the terms a bound is made of, a negative bound is the
// round-off of 0 (a start exactly on the shrunk edge) and is taken as 0.
constexpr double kRoundOffTight = 1e-12;

// The support polygon's rows in displacement units [m], one per edge of the hull of the n
// ground points pts (support_hull): G_e = a_e^T J_xy (jac: the CoM Jacobian's x and y rows,
// each nv long) and h_e = gain (-margin - o_e - a_e^T c_xy), into G (n, nv) and h (n,) (the
// first e rows written); their count e (0: no polygon) and, in fewest, the fewest nonzero
// entries of a row (nv where e = 0).
inline i64 support_rows(const double* pts, i64 n, const double* jac_x, const double* jac_y, i64 nv, double cx,
                        double cy, double margin, double gain, double* normals, double* offsets, double* G,
                        double* h, i64& fewest) {
    fewest = nv;
    const i64 e = support_hull(pts, n, normals, offsets);
    for (i64 r = 0; r < e; ++r) {
        const double ax = normals[2 * r], ay = normals[2 * r + 1];
        double* g = G + r * nv;
        i64 count = 0;
        for (i64 v = 0; v < nv; ++v) {
            g[v] = ax * jac_x[v] + ay * jac_y[v];
            count += g[v] != 0.0;
        }
        fewest = std::min(fewest, count);
        const double ac = ax * cx + ay * cy;
        double hr = gain * ((-margin - offsets[r]) - ac);
        // A CoM on the shrunk edge: h is 0, and its round-off (a few 1e-17 m) left below 0
        // made the start point infeasible by that much, which no level's answer then proved
        // (numerical_failure, a zero step). Within round-off of 0 it is 0.
        if (hr < 0.0 && hr >= -kRoundOffTight * gain * (std::fabs(margin) + std::fabs(offsets[r]) + std::fabs(ac)))
            hr = 0.0;
        h[r] = hr;
    }
    return e;
}

}  // namespace qpik::limits

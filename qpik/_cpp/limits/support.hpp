// The support polygon's edges: the convex hull of a few ground points (x, y) [m] by Andrew's
// monotone chain, for qpik.limits.SupportPolygonLimit. A humanoid's two box soles make eight
// points; scipy's Qhull spends about 90 us on its set-up for them, this about 1 us. Mesh
// soles make hundreds (Talos: 156 hull vertices a foot); those well inside the octagon of
// the extreme points (drop_inside) are left out before the sort.
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
#include "../core/linalg.hpp"

namespace qpik::limits {

inline constexpr double kTurn = 1e-10;

// The largest of `largest` and |x| as NumPy's max takes it (a NaN, once met, stays): the
// step of a row's largest entry for the negligible-row rule (qpik.diffik.boxes).
inline double numpy_max_abs(double largest, double x) {
    const double a = std::fabs(x);
    return (a > largest || a != a) && largest == largest ? a : largest;
}

struct HullPoint {
    double x, y;
    i64 index;
};

// Below this distance, as a fraction of the points' extent, a point is not taken as inside
// the octagon of drop_inside: far above the round-off of its tests (a few 1e-16 of the
// extent), and ten times the chain's own slack kTurn.
inline constexpr double kInside = 1e-9;

// The points of pts (the first in `sorted`, each with its index) that may be vertices of
// their hull, moved to the front of `sorted` in their order; their count returned. A point
// at least kInside extent inside the convex polygon of the extreme points ext (vertex
// indices, in the hull's counter-clockwise order, repeats allowed) is inside the hull by as
// much: the chain would pop it, and a point that far inside never turns the chain where a
// vertex is (the chain's answer is the same without it). (Akl and Toussaint's heuristic: on
// a humanoid's two soles, the inner sides of both feet.)
inline i64 drop_inside(std::vector<HullPoint>& sorted, const i64* ext, double extent) {
    using core::simd::v2d;
    using core::simd::v2i;
    const i64 n = static_cast<i64>(sorted.size());
    // The octagon's edges two at a time (lanes), a missing one (repeated vertex) always met:
    // a zero edge with a negative bound.
    v2d ax[4], ay[4], ex[4], ey[4], tol[4];
    for (int k = 0; k < 4; ++k) ax[k] = ay[k] = ex[k] = ey[k] = v2d{0.0, 0.0}, tol[k] = v2d{-1.0, -1.0};
    int edges = 0;
    for (int d = 0; d < 8; ++d) {
        const HullPoint& a = sorted[static_cast<size_t>(ext[d])];
        const HullPoint& b = sorted[static_cast<size_t>(ext[(d + 1) % 8])];
        const double dx = b.x - a.x, dy = b.y - a.y;
        if (dx == 0.0 && dy == 0.0) continue;  // (the same point twice: no edge)
        ax[edges / 2][edges % 2] = a.x;
        ay[edges / 2][edges % 2] = a.y;
        ex[edges / 2][edges % 2] = dx;
        ey[edges / 2][edges % 2] = dy;
        tol[edges / 2][edges % 2] = kInside * extent * std::sqrt(dx * dx + dy * dy);
        ++edges;
    }
    if (edges < 3) return n;
    i64 kept = 0;
    for (i64 i = 0; i < n; ++i) {  // (no branch on the tests: a point is copied either way)
        const HullPoint p = sorted[static_cast<size_t>(i)];
        const v2d px = {p.x, p.x}, py = {p.y, p.y};
        // inside: to the left of every edge, e x (p - a) > tol (the differences first: their
        // round-off is relative to the extent, whatever the points' distance from 0)
        v2i in = (ex[0] * (py - ay[0]) - ey[0] * (px - ax[0])) > tol[0];
        for (int k = 1; k < 4; ++k) in &= (ex[k] * (py - ay[k]) - ey[k] * (px - ax[k])) > tol[k];
        sorted[static_cast<size_t>(kept)] = p;
        kept += 1 + (in[0] & in[1]);  // (a lane's true is -1)
    }
    return kept;
}

// The hull of the n points pts (n, 2) row-major: its edge count e (at most n) with the edges'
// normals (e, 2) and offsets (e,) written into normals / offsets (n rows / entries each);
// 0 (nothing written) where the points span no area or one is not finite.
inline i64 support_hull(const double* pts, i64 n, double* normals, double* offsets) {
    using Point = HullPoint;
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
    // The first point of largest d . p for each of eight directions d, 45 degrees apart
    // counter-clockwise from +x (x, x + y, y, y - x, -x, -x - y, -y, x - y): the octagon
    // they make is inside the hull, its vertices in the hull's order.
    // (lanes: (x, y), (x + y, y - x) and their negatives; each lane's first largest, its
    // index held as a double: exact below 2^53)
    using core::simd::v2d;
    using core::simd::v2i;
    const v2d none = {-kInf, -kInf};
    v2d best[4] = {none, none, none, none}, at[4] = {};
    for (i64 i = 0; i < n; ++i) {
        const double x = pts[2 * i] * unit, y = pts[2 * i + 1] * unit;
        sorted[static_cast<size_t>(i)] = Point{x, y, i};
        const v2d xy = {x, y}, turned = {x + y, y - x}, index = {static_cast<double>(i), static_cast<double>(i)};
        const v2d key[4] = {xy, turned, -xy, -turned};
#pragma GCC unroll 4
        for (int k = 0; k < 4; ++k) {
            const v2i more = key[k] > best[k];
            best[k] = more ? key[k] : best[k];
            at[k] = more ? index : at[k];
        }
    }
    // the extent: the largest x less the smallest, max x + max(-x) (exactly max x - min x),
    // and y's alike
    const double extent = std::max(best[0][0] + best[2][0], best[0][1] + best[2][1]);
    // counter-clockwise from +x: x, x + y, y, y - x, -x, -x - y, -y, x - y
    const i64 ext[8] = {static_cast<i64>(at[0][0]), static_cast<i64>(at[1][0]), static_cast<i64>(at[0][1]),
                        static_cast<i64>(at[1][1]), static_cast<i64>(at[2][0]), static_cast<i64>(at[3][0]),
                        static_cast<i64>(at[2][1]), static_cast<i64>(at[3][1])};
    n = drop_inside(sorted, ext, extent);
    // (x, then y, then the index: a total order, the same sort on every machine)
    std::sort(sorted.begin(), sorted.begin() + n, [](const Point& a, const Point& b) {
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

// The support polygon's rows in displacement units [m], one per edge of its hull (e edges,
// support_hull's normals (e, 2) and offsets (e,)): G_e = a_e^T J_xy (jac: the CoM Jacobian's
// x and y rows, each nv long) and h_e = gain (-margin - o_e - a_e^T c_xy), into G (e, nv)
// and h (e,); in fewest, the fewest nonzero entries of a row (nv where e = 0). A row whose
// every entry is at most `negligible` in size is made zero (qpik.limits.collision.NEGLIGIBLE_ROW:
// a CoM that the joints barely move carries no direction; 0: none).
inline void support_rows(const double* normals, const double* offsets, i64 e, const double* jac_x,
                         const double* jac_y, i64 nv, double cx, double cy, double margin, double gain, double* G,
                         double* h, i64& fewest, double negligible = 0.0) {
    fewest = nv;
    for (i64 r = 0; r < e; ++r) {
        const double ax = normals[2 * r], ay = normals[2 * r + 1];
        double* g = G + r * nv;
        i64 count = 0;
        double largest = 0.0;
        for (i64 v = 0; v < nv; ++v) {
            g[v] = ax * jac_x[v] + ay * jac_y[v];
            count += g[v] != 0.0;
            largest = numpy_max_abs(largest, g[v]);
        }
        if (largest > 0.0 && largest <= negligible) {
            std::fill(g, g + nv, 0.0);
            count = 0;
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
}

}  // namespace qpik::limits

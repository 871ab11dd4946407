// Kinematics of a serial chain of hinge and slide joints (named for Python in
// qpik/model/kernels.py; recorded answers pin its bits).
//
// Kinematics follow MuJoCo's mj_kinematics: per body on the chain, p <- p + R body_pos,
// R <- R body_rot; then per joint of the body, the axis R axis and anchor p + R jnt_pos in
// the world frame; a hinge rotates R about its local axis by q - qpos0 and keeps the
// anchor fixed, a slide moves p along the axis by q - qpos0. The frame Jacobian (mj_jac)
// has, per dof, [u x (p_f - a); u] for a hinge and [u; 0] for a slide ([v; omega]).
#pragma once

#include <cmath>
#include <vector>

#include "../common.hpp"
#include "../detmath.hpp"

namespace qpik::model {

constexpr i64 HINGE = 0;
constexpr i64 SLIDE = 1;

// The arrays of qpik.model.KinematicChain (views, owned by the caller). Matrices of 3x3
// are row-major blocks of 9 doubles.
struct Chain {
    i64 nbody = 0;
    i64 njnt = 0;
    const double* body_pos = nullptr;   // (nbody, 3)
    const double* body_rot = nullptr;   // (nbody, 3, 3)
    const i64* jnt_start = nullptr;     // (nbody + 1,)
    const i64* jnt_type = nullptr;      // (njnt,)
    const double* jnt_axis = nullptr;   // (njnt, 3)
    const double* jnt_pos = nullptr;    // (njnt, 3)
    const i64* jnt_qadr = nullptr;      // (njnt,)
    const i64* jnt_dadr = nullptr;      // (njnt,)
    const double* jnt_qpos0 = nullptr;  // (njnt,)
    const double* frame_pos = nullptr;  // (3,)
    const double* frame_rot = nullptr;  // (3, 3)
};

// Rotation matrix about unit `axis` of the angle whose cosine and sine are c, s (Rodrigues),
// into out (3x3).
inline void axis_rotation_cs(const double* axis, double c, double s, double* out) {
    double x = axis[0], y = axis[1], z = axis[2];
    double t = 1.0 - c;
    out[0] = t * x * x + c;
    out[1] = t * x * y - s * z;
    out[2] = t * x * z + s * y;
    out[3] = t * x * y + s * z;
    out[4] = t * y * y + c;
    out[5] = t * y * z - s * x;
    out[6] = t * x * z - s * y;
    out[7] = t * y * z + s * x;
    out[8] = t * z * z + c;
}

// Rotation matrix of `angle` [rad] about unit `axis` (Rodrigues), into out (3x3).
inline void axis_rotation(const double* axis, double angle, double* out) {
    double c, s;
    dm::sincos(angle, s, c);
    axis_rotation_cs(axis, c, s, out);
}

// Rotation matrices (k, 3, 3) of unit quaternions (k, 4) (w, x, y, z).
inline void quat2mat(const double* quat, i64 k_count, double* out) {
    for (i64 k = 0; k < k_count; ++k) {
        const double* qk = quat + 4 * k;
        double* o = out + 9 * k;
        double w = qk[0], x = qk[1], y = qk[2], z = qk[3];
        o[0] = w * w + x * x - y * y - z * z;
        o[4] = w * w - x * x + y * y - z * z;
        o[8] = w * w - x * x - y * y + z * z;
        o[1] = 2.0 * (x * y - w * z);
        o[2] = 2.0 * (x * z + w * y);
        o[3] = 2.0 * (x * y + w * z);
        o[5] = 2.0 * (y * z - w * x);
        o[6] = 2.0 * (x * z - w * y);
        o[7] = 2.0 * (y * z + w * x);
    }
}

inline void matmul3(const double* A, const double* B, double* out) {
    for (int i = 0; i < 3; ++i) {
        double a0 = A[3 * i], a1 = A[3 * i + 1], a2 = A[3 * i + 2];
        for (int j = 0; j < 3; ++j) out[3 * i + j] = a0 * B[j] + a1 * B[3 + j] + a2 * B[6 + j];
    }
}

inline void copy3(const double* src, double* dst) {
    for (int i = 0; i < 9; ++i) dst[i] = src[i];
}

// Walk the chain at q: world axes and anchors of its joints (njnt, 3) and the frame's pose
// (position (3,) [m], rotation (3, 3)).
inline void walk(const Chain& c, const double* q, MatRef axes, MatRef anchors, double* position,
                 double* rotation) {
    double R[9], tmp[9], rot[9], p[3];
    for (int i = 0; i < 3; ++i) {
        p[i] = 0.0;
        for (int j = 0; j < 3; ++j) R[3 * i + j] = i == j ? 1.0 : 0.0;
    }
    for (i64 b = 0; b < c.nbody; ++b) {
        const double* bp = c.body_pos + 3 * b;
        for (int i = 0; i < 3; ++i)
            p[i] += R[3 * i] * bp[0] + R[3 * i + 1] * bp[1] + R[3 * i + 2] * bp[2];
        matmul3(R, c.body_rot + 9 * b, tmp);
        copy3(tmp, R);
        for (i64 j = c.jnt_start[b]; j < c.jnt_start[b + 1]; ++j) {
            const double* ax = c.jnt_axis + 3 * j;
            const double* jp = c.jnt_pos + 3 * j;
            for (int i = 0; i < 3; ++i) {
                axes(j, i) = R[3 * i] * ax[0] + R[3 * i + 1] * ax[1] + R[3 * i + 2] * ax[2];
                anchors(j, i) = p[i] + R[3 * i] * jp[0] + R[3 * i + 1] * jp[1] + R[3 * i + 2] * jp[2];
            }
            double value = q[c.jnt_qadr[j]] - c.jnt_qpos0[j];
            if (c.jnt_type[j] == HINGE) {
                axis_rotation(ax, value, rot);
                matmul3(R, rot, tmp);
                copy3(tmp, R);
                for (int i = 0; i < 3; ++i)
                    p[i] = anchors(j, i) - (R[3 * i] * jp[0] + R[3 * i + 1] * jp[1] + R[3 * i + 2] * jp[2]);
            } else {
                for (int i = 0; i < 3; ++i) p[i] += axes(j, i) * value;
            }
        }
    }
    const double* fp = c.frame_pos;
    for (int i = 0; i < 3; ++i)
        position[i] = p[i] + R[3 * i] * fp[0] + R[3 * i + 1] * fp[1] + R[3 * i + 2] * fp[2];
    matmul3(R, c.frame_rot, rotation);
}

// The world-aligned Jacobian jac (6, jac.cols) [v; omega] of a point at position from the
// world axes and anchors (nj, 3) of the joints moving it: joint j is a hinge if hinge(j)
// (else a slide) and moves dof dof(j); columns of other dofs zero.
template <class IsHinge, class Dof>
inline void axes_jacobian(const double* position, MatRef axes, MatRef anchors, i64 nj, IsHinge hinge, Dof dof,
                          MatRef jac) {
    for (int i = 0; i < 6; ++i)
        for (i64 j = 0; j < jac.cols; ++j) jac(i, j) = 0.0;
    for (i64 j = 0; j < nj; ++j) {
        i64 d = dof(j);
        double u0 = axes(j, 0), u1 = axes(j, 1), u2 = axes(j, 2);
        if (hinge(j)) {
            double r0 = position[0] - anchors(j, 0);
            double r1 = position[1] - anchors(j, 1);
            double r2 = position[2] - anchors(j, 2);
            jac(0, d) += u1 * r2 - u2 * r1;
            jac(1, d) += u2 * r0 - u0 * r2;
            jac(2, d) += u0 * r1 - u1 * r0;
            jac(3, d) += u0;
            jac(4, d) += u1;
            jac(5, d) += u2;
        } else {
            jac(0, d) += u0;
            jac(1, d) += u1;
            jac(2, d) += u2;
        }
    }
}

// fk_jac with the scratch axes, anchors (njnt, 3) given.
inline void fk_jac_in(const Chain& c, const double* q, MatRef axes, MatRef anchors, double* position,
                      double* rotation, MatRef jac, bool want_jac) {
    walk(c, q, axes, anchors, position, rotation);
    if (!want_jac) return;
    axes_jacobian(position, axes, anchors, c.njnt, [&c](i64 j) { return c.jnt_type[j] == HINGE; },
                  [&c](i64 j) { return c.jnt_dadr[j]; }, jac);
}

// Pose of the chain's frame at q (position (3,) [m], rotation (3, 3)) and, if want_jac,
// its world-aligned Jacobian jac (6, nv) [v; omega] (columns of dofs off the chain zero).
inline void fk_jac(const Chain& c, const double* q, double* position, double* rotation, MatRef jac,
                   bool want_jac) {
    Mat axes(c.njnt, 3), anchors(c.njnt, 3);
    fk_jac_in(c, q, axes.ref(), anchors.ref(), position, rotation, jac, want_jac);
}

// ------------------------------------------------------------- the compact chain
// A Chain re-read once (the IGM does it once per solve) for many evaluations: the
// fixed transforms between consecutive joints (bodies without joints, body offsets) are
// composed into one per joint (and the trailing ones into the frame's), an identity
// rotation or a zero offset is skipped, and a hinge about a coordinate axis (+-x, +-y,
// +-z, the usual case) rotates two columns of R by (cos, sin) instead of a general
// Rodrigues product. The same kinematics as walk (MuJoCo's), rounded differently
// (to a few ulps); the IGM's bits are its own (tests/fixtures/model.npz).
struct FastJoint {
    double pos[3];  // fixed offset before the joint, in the frame before it
    double rot[9];  // fixed rotation before the joint
    bool has_pos, has_rot;
    bool hinge;
    int axis_index;     // 0, 1, 2: the hinge turns about +-e_k (axis_sign); -1: general
    int turn_a, turn_b;  // with axis_index k: the columns k + 1, k + 2 (mod 3) that turn
    double axis_sign;   // +-1 with axis_index >= 0
    bool has_anchor;    // jnt_pos != 0
    const double* axis;
    const double* anchor;
    i64 qadr, dadr;
    double qpos0;
};

struct FastChain {
    std::vector<FastJoint> joints;
    double frame_pos[3], frame_rot[9];
    bool frame_has_rot;
};

inline bool is_identity3(const double* R) {
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (R[3 * i + j] != (i == j ? 1.0 : 0.0)) return false;
    return true;
}

// Compose the fixed transform (pos, rot) with (bp, br): pos += rot bp, rot = rot br.
inline void compose_fixed(double* pos, double* rot, const double* bp, const double* br) {
    double tmp[9];
    for (int i = 0; i < 3; ++i) pos[i] += rot[3 * i] * bp[0] + rot[3 * i + 1] * bp[1] + rot[3 * i + 2] * bp[2];
    matmul3(rot, br, tmp);
    copy3(tmp, rot);
}

inline FastChain fast_chain(const Chain& c) {
    FastChain f;
    f.joints.reserve(static_cast<size_t>(c.njnt));
    double pos[3] = {0.0, 0.0, 0.0};
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    auto reset = [&]() {
        for (int i = 0; i < 3; ++i) pos[i] = 0.0;
        for (int i = 0; i < 9; ++i) rot[i] = (i % 4 == 0) ? 1.0 : 0.0;
    };
    for (i64 b = 0; b < c.nbody; ++b) {
        compose_fixed(pos, rot, c.body_pos + 3 * b, c.body_rot + 9 * b);
        for (i64 j = c.jnt_start[b]; j < c.jnt_start[b + 1]; ++j) {
            FastJoint J;
            for (int i = 0; i < 3; ++i) J.pos[i] = pos[i];
            for (int i = 0; i < 9; ++i) J.rot[i] = rot[i];
            J.has_pos = pos[0] != 0.0 || pos[1] != 0.0 || pos[2] != 0.0;
            J.has_rot = !is_identity3(rot);
            J.hinge = c.jnt_type[j] == HINGE;
            J.axis = c.jnt_axis + 3 * j;
            J.anchor = c.jnt_pos + 3 * j;
            J.has_anchor = J.anchor[0] != 0.0 || J.anchor[1] != 0.0 || J.anchor[2] != 0.0;
            J.axis_index = -1;
            J.axis_sign = 1.0;
            for (int k = 0; k < 3; ++k) {
                double a = J.axis[k], o1 = J.axis[(k + 1) % 3], o2 = J.axis[(k + 2) % 3];
                if ((a == 1.0 || a == -1.0) && o1 == 0.0 && o2 == 0.0) {
                    J.axis_index = k;
                    J.axis_sign = a;
                }
            }
            J.turn_a = J.turn_b = 0;
            if (J.axis_index >= 0) {
                J.turn_a = (J.axis_index + 1) % 3;
                J.turn_b = (J.axis_index + 2) % 3;
            }
            J.qadr = c.jnt_qadr[j];
            J.dadr = c.jnt_dadr[j];
            J.qpos0 = c.jnt_qpos0[j];
            f.joints.push_back(J);
            reset();  // the next joint's offset starts at this one
        }
    }
    compose_fixed(pos, rot, c.frame_pos, c.frame_rot);
    for (int i = 0; i < 3; ++i) f.frame_pos[i] = pos[i];
    for (int i = 0; i < 9; ++i) f.frame_rot[i] = rot[i];
    f.frame_has_rot = !is_identity3(rot);
    return f;
}

// R <- R Rot(e_k, angle) for a hinge about the coordinate axis k (s: the signed sine):
// the columns a = k + 1, b = k + 2 (mod 3) turn, e_a -> c e_a + s e_b.
inline void rotate_about_axis(double* R, int a, int b, double c, double s) {
    for (int i = 0; i < 3; ++i) {
        double ra = R[3 * i + a], rb = R[3 * i + b];
        R[3 * i + a] = c * ra + s * rb;
        R[3 * i + b] = c * rb - s * ra;
    }
}

// Pose of the frame at q (position, rotation) and its Jacobian jac (6, nq) [v; omega]
// (columns of dofs off the chain zero), through the FastChain f; axes, anchors (njnt, 3).
inline void fast_fk_jac(const FastChain& f, const double* q, MatRef axes, MatRef anchors, double* position,
                        double* rotation, MatRef jac) {
    double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double p[3] = {0.0, 0.0, 0.0};
    double tmp[9], rot[9];
    i64 nj = static_cast<i64>(f.joints.size());
    for (i64 j = 0; j < nj; ++j) {
        const FastJoint& J = f.joints[static_cast<size_t>(j)];
        if (J.has_pos)
            for (int i = 0; i < 3; ++i)
                p[i] += R[3 * i] * J.pos[0] + R[3 * i + 1] * J.pos[1] + R[3 * i + 2] * J.pos[2];
        if (J.has_rot) {
            matmul3(R, J.rot, tmp);
            copy3(tmp, R);
        }
        double* u = axes.row(j);
        double* a = anchors.row(j);
        if (J.axis_index >= 0) {
            for (int i = 0; i < 3; ++i) u[i] = J.axis_sign * R[3 * i + J.axis_index];
        } else {
            const double* ax = J.axis;
            for (int i = 0; i < 3; ++i) u[i] = R[3 * i] * ax[0] + R[3 * i + 1] * ax[1] + R[3 * i + 2] * ax[2];
        }
        const double* jp = J.anchor;
        if (J.has_anchor) {
            for (int i = 0; i < 3; ++i) a[i] = p[i] + R[3 * i] * jp[0] + R[3 * i + 1] * jp[1] + R[3 * i + 2] * jp[2];
        } else {
            for (int i = 0; i < 3; ++i) a[i] = p[i];
        }
        double value = q[J.qadr] - J.qpos0;
        if (J.hinge) {
            double c, s;
            dm::sincos(value, s, c);
            if (J.axis_index >= 0) {
                rotate_about_axis(R, J.turn_a, J.turn_b, c, J.axis_sign * s);
            } else {
                axis_rotation_cs(J.axis, c, s, rot);  // (the sine and cosine above)
                matmul3(R, rot, tmp);
                copy3(tmp, R);
            }
            if (J.has_anchor)
                for (int i = 0; i < 3; ++i)
                    p[i] = a[i] - (R[3 * i] * jp[0] + R[3 * i + 1] * jp[1] + R[3 * i + 2] * jp[2]);
        } else {
            for (int i = 0; i < 3; ++i) p[i] += u[i] * value;
        }
    }
    const double* fp = f.frame_pos;
    for (int i = 0; i < 3; ++i)
        position[i] = p[i] + R[3 * i] * fp[0] + R[3 * i + 1] * fp[1] + R[3 * i + 2] * fp[2];
    if (f.frame_has_rot)
        matmul3(R, f.frame_rot, rotation);
    else
        copy3(R, rotation);
    axes_jacobian(position, axes, anchors, nj, [&f](i64 j) { return f.joints[static_cast<size_t>(j)].hinge; },
                  [&f](i64 j) { return f.joints[static_cast<size_t>(j)].dadr; }, jac);
}

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

inline double dist3(const double* a, const double* b) {
    double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}

// Closest points s on a1 + t u1 and r on a2 + t u2 (unit directions); for parallel lines,
// a1 and its projection on the second line.
inline void feet(const double* a1, const double* u1, const double* a2, const double* u2, double* s,
                 double* r) {
    double w[3];
    for (int i = 0; i < 3; ++i) w[i] = a1[i] - a2[i];
    double b = dot3(u1, u2);
    double d = dot3(u1, w);
    double e = dot3(u2, w);
    double den = 1.0 - b * b;
    double t1, t2;
    if (den < 1e-12) {
        t1 = 0.0;
        t2 = e;
    } else {
        t1 = (b * e - d) / den;
        t2 = (e - b * d) / den;
    }
    for (int i = 0; i < 3; ++i) {
        s[i] = a1[i] + t1 * u1[i];
        r[i] = a2[i] + t2 * u2[i];
    }
}

// Length of the path s_1 -> r_2 -> s_2 -> ... -> s_m -> frame through the feet of the
// common perpendiculars of consecutive hinge axes at q; center receives s_1. Without a
// hinge, the frame position at q and 0.
inline double reach_radius(const Chain& c, const double* q, double* center) {
    i64 nj = c.njnt;
    Mat axes(nj, 3), anchors(nj, 3);
    double p[3], rotation[9], s[3], r[3], previous[3] = {0.0, 0.0, 0.0};
    walk(c, q, axes.ref(), anchors.ref(), p, rotation);
    bool first = true;
    double length = 0.0;
    for (int i = 0; i < 3; ++i) center[i] = p[i];
    for (i64 j = 0; j < nj; ++j) {
        if (c.jnt_type[j] != HINGE) continue;
        i64 nxt = -1;
        for (i64 k = j + 1; k < nj; ++k) {
            if (c.jnt_type[k] == HINGE) {
                nxt = k;
                break;
            }
        }
        if (nxt >= 0) {
            feet(anchors.row(j), axes.row(j), anchors.row(nxt), axes.row(nxt), s, r);
        } else {
            double w[3];
            for (int i = 0; i < 3; ++i) w[i] = p[i] - anchors(j, i);
            double t = dot3(axes.row(j), w);
            for (int i = 0; i < 3; ++i) s[i] = anchors(j, i) + axes(j, i) * t;
        }
        if (first) {
            for (int i = 0; i < 3; ++i) center[i] = s[i];
            first = false;
        } else {
            length += dist3(s, previous);
        }
        if (nxt >= 0) {
            length += dist3(r, s);
            for (int i = 0; i < 3; ++i) previous[i] = r[i];
        } else {
            length += dist3(p, s);
        }
    }
    return length;
}

}  // namespace qpik::model

// Bindings of the limits layer (qpik._engine.limits): the conservative culling of collision
// pairs (limits/collision.hpp), used by qpik.limits.collision. Every shape and geom id is
// checked here, so a bad argument raises ValueError instead of reading out of bounds.
#include <cstdint>

#include "bind.hpp"
#include "limits/collision.hpp"

namespace nb = nanobind;
using namespace qpik;
using namespace qpik::bind;

void bind_limits(nb::module_& m) {
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
}

"""The model layer: what qpik reads from a MuJoCo model, one module each.

- :mod:`qpik.model.configuration`: :class:`qpik.Configuration`, the state object (model,
  data, ``q``, limits, frame poses and Jacobians through MuJoCo);
- :mod:`qpik.model.frames`: frame types, the FrameType → ``mjtObj`` map and the resolver
  of frame keys (``resolve_frame``);
- :mod:`qpik.model.rotations`: the orientation error and rotation helpers;
- :mod:`qpik.model.chain`: a frame's kinematic chain read into arrays, with compiled
  (C++) forward kinematics and Jacobians (kernels in :mod:`qpik.model.kernels`);
- :mod:`qpik.model.couplings`: the joint and tendon couplings the model states
  (``<equality><joint>``, URDF ``<mimic>``), as rows ``r(q) = 0``.

The chain names are imported lazily, so that ``import qpik.model.frames`` does not load
the compiled kernels.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the type checker sees the names; at run time __getattr__ loads them
    from .chain import (
        KinematicChain,
        ReachBound,
        chain_qpos_mask,
        chain_support,
        joint_limit_arrays,
    )
    from .couplings import Couplings, model_couplings

__all__ = [
    "Couplings",
    "KinematicChain",
    "ReachBound",
    "chain_qpos_mask",
    "chain_support",
    "joint_limit_arrays",
    "model_couplings",
]


def __getattr__(name: str) -> Any:
    if name in ("Couplings", "model_couplings"):
        from . import couplings

        return getattr(couplings, name)
    if name in __all__:
        from . import chain

        return getattr(chain, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

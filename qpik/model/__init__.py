"""The model layer: a frame's kinematic chain read from a MuJoCo model into arrays, with
compiled (numba) forward kinematics and Jacobians (:mod:`qpik.model.chain`)."""

from .chain import KinematicChain, ReachBound, chain_support, joint_limits

__all__ = ["KinematicChain", "ReachBound", "chain_support", "joint_limits"]

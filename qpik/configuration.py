"""Where qpik's state object has always been imported from: :class:`Configuration`,
:class:`FrameType`, :func:`frame_names` and :func:`joint_names`, which live in the model
layer (:mod:`qpik.model.configuration`, :mod:`qpik.model.frames`)."""

from .model.configuration import (  # noqa: F401 (re-exported)
    Configuration,
    FrameType,
    _qpos_joint_names,
    as_configuration,
    frame_names,
    joint_names,
)

__all__ = ["Configuration", "FrameType", "frame_names", "joint_names"]

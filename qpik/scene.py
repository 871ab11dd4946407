"""Scenes: obstacles added to a robot model, for collision avoidance (the public path over
:mod:`qpik.model.scene`)."""

from .model.scene import SHAPES, add_obstacle, model_recipe

__all__ = ["SHAPES", "add_obstacle", "model_recipe"]

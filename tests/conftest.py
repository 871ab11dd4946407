"""Shared fixtures: bundled robots and seeded random generators."""

from __future__ import annotations

import numpy as np
import pytest

import qpik


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(params=qpik.list_robots())
def bundled_robot(request) -> str:
    return request.param


def configuration_of(name: str, q=None) -> qpik.Configuration:
    """A fresh configuration of a bundled robot (fresh per test: tests never share state)."""
    return qpik.Configuration(qpik.load_robot(name), q)

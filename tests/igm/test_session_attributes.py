"""An IKSession's attributes set after it was built: its ``options`` (the defaults of its
solves) are settable and checked as the constructor's; its ``model`` is fixed (the
session's preparation is of it: before, an assigned model was silently mixed with the old
preparation, and the solve answered for the old robot)."""

from __future__ import annotations

import numpy as np
import pytest

import qpik
from qpik.errors import InvalidOption, ReadOnlyAttribute

TARGET = {"ee": [0.4, 0.1, 0.4]}


def test_the_model_of_a_session_is_read_only():
    session = qpik.IKSession("panda")
    before = session.solve(TARGET).q.copy()
    with pytest.raises(ReadOnlyAttribute, match="IKSession.model") as info:
        session.model = qpik.load_robot("ur5e")
    assert isinstance(info.value, AttributeError)
    assert session.model.nq == 7
    np.testing.assert_array_equal(session.solve(TARGET).q, before)


def test_session_options_set_after_the_build_are_checked_and_used():
    """A preset name or options assigned: the next solves use them, bit for bit as a
    session built with them; a value that is neither: InvalidOption, the old ones kept."""
    session = qpik.IKSession("panda")
    session.solve(TARGET)
    session.options = qpik.SolveOptions(tol_position=1e-2, max_iters=3)
    fresh = qpik.IKSession("panda", qpik.SolveOptions(tol_position=1e-2, max_iters=3))
    mine, theirs = session.solve(TARGET), fresh.solve(TARGET)
    np.testing.assert_array_equal(mine.q, theirs.q)
    assert mine.iterations == theirs.iterations
    session.options = "default"
    assert session.options == qpik.IKSession("panda").options
    for value in ("no such preset", 3, {"tol_position": 1e-3}):
        with pytest.raises(InvalidOption, match="options"):
            session.options = value  # type: ignore[assignment]
    assert session.options == qpik.IKSession("panda").options


def test_a_model_edited_in_place_is_read_again_by_the_session():
    """A joint range narrowed in the model after the session was built: the next solve
    reads the model again and answers as a new session does, bit for bit, within the new
    range (before: the session's preparation kept the old range, and its answer, 0.29 rad
    on a joint now limited to 0.05, was reported converged)."""
    model = qpik.load_robot("panda")
    session = qpik.IKSession(model)
    target = {"ee": [0.4, 0.3, 0.4]}
    assert abs(session.solve(target).q[0]) > 0.2
    model.jnt_range[0] = [-0.05, 0.05]
    narrowed = session.solve(target)
    assert abs(narrowed.q[0]) <= 0.05
    np.testing.assert_array_equal(narrowed.q, qpik.IKSession(model).solve(target).q)

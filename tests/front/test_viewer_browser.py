"""The viewer in a real browser: headless Chromium (SwiftShader WebGL) opens the page that
``qpik.viewer.Viewer`` serves on a free local port, waits for the scene and its panels,
and checks what it shows. Marked ``browser``: deselected by the plain ``pytest -q``; run
with ``pytest -m browser`` (``.ci/run`` does, where they must pass, never skip).

The screenshots are written to ``$QPIK_SCREENSHOT_DIR`` when set (else the test's
temporary folder), to be looked at.
"""

from __future__ import annotations

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

TASKS = Path(__file__).resolve().parents[2] / "tasks"


def _needs() -> None:
    """The browser tests need viser and Chromium: missing, they fail (never skip)."""
    import viser  # noqa: F401  (ImportError: install the viewer extra)

    from qpik.viewer.browser import find_chromium

    assert find_chromium(), "no Chromium: apt-get install chromium (or set QPIK_CHROMIUM)"


@pytest.fixture
def shots(tmp_path) -> Path:
    folder = Path(os.environ.get("QPIK_SCREENSHOT_DIR") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture(scope="module")
def browser():
    _needs()
    from qpik.viewer.browser import Browser

    with Browser(width=1200, height=800) as b:
        yield b


def pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def scene_region(image: np.ndarray) -> np.ndarray:
    """The 3-D view without the panel (right) and viser's notices (top left)."""
    h, w, _ = image.shape
    return image[int(0.22 * h) : int(0.95 * h), int(0.05 * w) : int(0.70 * w)]


def drawn_fraction(image: np.ndarray) -> float:
    """Fraction of the scene region far from the background colour (white, light grid)."""
    region = scene_region(image)
    return float(np.mean(np.abs(region - 255).sum(axis=2) > 60))


def wait_for_scene(browser, timeout: float = 90.0) -> bytes:
    """Screenshots until two in a row agree (the scene has loaded and faded in)."""
    deadline = time.monotonic() + timeout
    previous = None
    while time.monotonic() < deadline:
        png = browser.screenshot()
        image = pixels(png)
        if (
            previous is not None
            and drawn_fraction(image) > 0.005
            and np.abs(image - previous).sum(axis=2).max(initial=0) < 30
        ):
            return png
        previous = image
        time.sleep(1.0)
    raise AssertionError(f"the scene never settled within {timeout} s")


def changed_fraction(a: bytes, b: bytes) -> float:
    return float(
        np.mean(np.abs(scene_region(pixels(a)) - scene_region(pixels(b))).sum(axis=2) > 30)
    )


def test_panda_problem_in_the_browser(browser, shots):
    from qpik.viewer import Viewer

    with Viewer(TASKS / "panda_pose_reach.toml", port=0) as viewer:
        assert viewer.url.startswith("http://127.0.0.1:")
        browser.open(viewer.url)
        text = browser.wait_for_text("Level 0: met", "Level 1", "status: solved", "solve time:")
        assert "tasks: position ee, orientation ee" in text
        first = wait_for_scene(browser)
        (shots / "viewer_panda_start.png").write_bytes(first)
        assert drawn_fraction(pixels(first)) > 0.01, "the scene is blank"
        # the panel: one block per level, green for a met level
        assert browser.evaluate("document.querySelectorAll('.qpik-level').length") == 2
        assert browser.evaluate("document.querySelectorAll('.qpik-met').length") >= 1

        # move the target through the Python API: the solved q follows, the page redraws
        q_before = viewer.q
        position, rotation = viewer.frame_pose("ee")
        goal = position + np.array([-0.1, -0.25, 0.15])
        report = viewer.set_target("ee", goal, rotation)
        assert report.converged
        reached, _ = viewer.frame_pose("ee")
        assert np.linalg.norm(reached - goal) < 1e-3
        assert np.linalg.norm(viewer.q - q_before) > 0.1
        browser.wait_for_text(f"{report.steps} steps, converged")
        moved = wait_for_scene(browser)
        (shots / "viewer_panda_moved.png").write_bytes(moved)
        assert changed_fraction(first, moved) > 0.002, "the screenshot did not change"
        # the q shown in the page is the solved one
        shown = browser.evaluate(
            "[...document.querySelectorAll('textarea')].map(t => t.value).join('|')"
        )
        assert f"{viewer.q[0]:.6f}" in shown and f"{viewer.q[3]:.6f}" in shown

        # a target out of reach: level 0 cannot be met, its panel turns red
        viewer.set_target("ee", np.array([1.5, 0.0, 0.5]), rotation)
        text = browser.wait_for_text("Level 0: cannot be met")
        assert "not converged" in text
        colour = browser.evaluate(
            "getComputedStyle(document.querySelector('.qpik-unmet')).borderLeftColor"
        )
        assert colour == "rgb(198, 40, 40)"
        red = wait_for_scene(browser)
        (shots / "viewer_panda_unreachable.png").write_bytes(red)


def test_drag_through_the_handle_callback(browser):
    """A handle update (what a drag in the page sends) reaches the solver thread."""
    from types import SimpleNamespace

    from qpik.viewer import Viewer

    with Viewer("panda", port=0) as viewer:
        browser.open(viewer.url)
        browser.wait_for_text("Level 0: met")
        frame = viewer.goals[0]
        position, rotation = viewer.frame_pose(frame)
        handle = SimpleNamespace(position=position + [0.0, 0.05, 0.05], wxyz=[0, 1, 0, 0])
        from qpik.viewer.app import _wxyz

        handle.wxyz = _wxyz(rotation)
        viewer._on_handle(frame)(SimpleNamespace(target=handle, phase="update"))
        deadline = time.monotonic() + 30
        while not viewer.drag_times and time.monotonic() < deadline:
            time.sleep(0.05)
        assert viewer.drag_times, "the solver thread never solved the drag"
        time.sleep(0.2)
        reached, _ = viewer.frame_pose(frame)
        assert np.linalg.norm(reached - handle.position) < 1e-3
        browser.wait_for_text("converged")


def test_talos_meshes_in_the_browser(browser, shots):
    from qpik.problem import load_problem
    from qpik.viewer import Viewer

    problem = load_problem(TASKS / "talos_both_hands.toml")
    with Viewer(problem, port=0) as viewer:
        browser.open(viewer.url)
        text = browser.wait_for_text("Level 0", "Level 3", "solve time:")
        assert "status: solved" in text
        shot = wait_for_scene(browser)
        (shots / "viewer_talos.png").write_bytes(shot)
        assert drawn_fraction(pixels(shot)) > 0.01
        # the support polygon (and the CoM) are drawn
        assert viewer.support_polygon is not None and len(viewer.support_polygon) >= 4
        assert "active limits:" in text

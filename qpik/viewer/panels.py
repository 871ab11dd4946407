"""The viewer's level panels as HTML (:func:`level_html`): a level's state, status,
residual, damping and goal error, coloured by its state."""

from __future__ import annotations

import html
import math

import numpy as np

from .live import LevelReport

__all__ = ["level_html"]

#: Colours of a level's state (border, background) in the panel.
_STATE_COLOURS = {
    "met": ("#2e7d32", "#e8f5e9"),
    "compromise": ("#b26a00", "#fff4e0"),
    "unmet": ("#c62828", "#ffebee"),
    "pending": ("#546e7a", "#eceff1"),
}
_STATE_WORDS = {"met": "met", "compromise": "met in part", "unmet": "cannot be met",
                "pending": "not solved since the robot moved"}  # fmt: skip


def _number(value: float) -> str:
    """``value`` to 3 significant digits; a dash for NaN (not solved since the robot moved)."""
    return "&ndash;" if math.isnan(value) else f"{value:.3g}"


def level_html(level: LevelReport) -> str:
    """A level's panel as HTML: state, status, residual, damping, the number of active
    limits (the limits bind the final step of every level alike; the summary lists
    them); a red border and background when it cannot be met."""
    border, background = _STATE_COLOURS[level.state]
    tasks = html.escape(", ".join(level.tasks) or "(no task)")
    count = len(level.active_limits)
    limits = f"{count} (listed above)" if count else "none"
    goal = ""
    if level.goal_error is not None:
        p, o = level.goal_error
        turn = "" if np.isnan(o) else f", {np.degrees(o):.3f}&deg;"  # (NaN: position only)
        goal = f"<br>goal error: {1000 * p:.2f} mm{turn}"
    return (
        f'<div class="qpik-level qpik-{level.state}" data-level="{level.index}" '
        f'style="border-left:5px solid {border};background:{background};'
        f'padding:4px 8px;margin:2px 0;font-size:0.85em;line-height:1.35">'
        f'<b style="color:{border}">Level {level.index}: {_STATE_WORDS[level.state]}</b><br>'
        f"tasks: {tasks}<br>"
        f"status: <b>{html.escape(level.status)}</b><br>"
        f"residual: {_number(level.residual)} &middot; damping: {_number(level.damping)}"
        f"{goal}<br>"
        f"active limits: {limits}</div>"
    )

"""``[solver]`` of a problem file: a :data:`qpik.options.PRESETS` name and overrides of
its :class:`qpik.SolveOptions` fields, typed and range-checked (:data:`.reader.RANGES`)."""

from __future__ import annotations

from typing import Any

from ..core.cascade import DampingLaw
from ..errors import InvalidOption
from ..options import PRESETS, SolveOptions
from .reader import RANGES, Reader
from .report import jsonable

#: The ``[solver]`` fields and their TOML types (ranges: :data:`.reader.RANGES`): a
#: preset of :data:`qpik.options.PRESETS` and overrides of its :class:`qpik.SolveOptions`.
_SOLVER_KEYS: dict[str, type] = {
    "preset": str,
    "solver": str,
    "tol_position": float,
    "tol_orientation": float,
    "max_iters": int,
    "restarts": int,
    "seed": int,
    "time_budget": float,
    "alpha": float,
    "beta": float,
    "max_step": list,
    "singular_threshold": float,
    "max_damping": float,
    "lower_trust": float,
    "adaptive_damping": bool,
    "damping": float,
    "stall_window": int,
}
#: ``[solver]`` fields of the solve mode only.
_SOLVE_ONLY = (
    "max_iters",
    "restarts",
    "time_budget",
    "alpha",
    "beta",
    "max_step",
    "seed",
    "stall_window",
)
#: ``[solver]`` fields passed to :class:`qpik.SolveOptions` as they are.
_OPTION_FIELDS = (
    "solver",
    "tol_position",
    "tol_orientation",
    "max_iters",
    "restarts",
    "seed",
    "time_budget",
    "alpha",
    "beta",
    "stall_window",
    "damping",
)
#: The preset of each mode when ``[solver]`` names none.
DEFAULT_PRESETS = {"solve": "default", "track": "tracking"}
#: The seed of a problem file's restarts when ``[solver]`` gives none (reproducible runs).
DEFAULT_SEED = 0


def read_solver(reader: Reader, data: dict, mode: str) -> tuple[dict[str, Any], SolveOptions]:
    """``[solver]``: each field typed and range-checked (solve-only fields in track mode
    are errors), and the :class:`qpik.SolveOptions` they make."""
    table = reader.table(data, "solver", "", _SOLVER_KEYS, "a [solver] table", {})
    options: dict[str, Any] = {}
    for key, kind in _SOLVER_KEYS.items():
        if key not in table:
            continue
        name = f"solver.{key}"
        if mode != "solve" and key in _SOLVE_ONLY:
            raise reader.fail(name, 'only with mode = "solve" (not used in tracking)')
        if key == "max_step":
            options[key] = _read_max_step(reader, table[key])
            continue
        options[key] = reader.get(table, key, "solver", kind)
        if name in RANGES:
            reader.number(options[key], name, name, reader._EXPECTED[kind])
    return options, _solve_options(reader, options, mode)


def _solve_options(reader: Reader, options: dict[str, Any], mode: str) -> SolveOptions:
    """The preset of ``options`` (default: the mode's) with the other fields over it."""
    preset = options.get("preset", DEFAULT_PRESETS[mode])
    if preset not in PRESETS:
        raise reader.fail(
            "solver.preset", f"one of {', '.join(map(repr, PRESETS))}, got {preset!r}"
        )
    base = PRESETS[preset]
    overrides: dict[str, Any] = {k: options[k] for k in _OPTION_FIELDS if k in options}
    overrides.setdefault("seed", DEFAULT_SEED)
    if "max_step" in options:
        step = options["max_step"]
        overrides["max_step"] = None if step is False else tuple(step)
    law = base.damping_law or DampingLaw()
    if not options.get("adaptive_damping", True):
        overrides["damping_law"] = None
    elif any(key in options for key in ("singular_threshold", "max_damping", "lower_trust")):
        overrides["damping_law"] = DampingLaw(
            singular_threshold=options.get("singular_threshold", law.singular_threshold),
            max_damping=options.get("max_damping", law.max_damping),
            error_scale=law.error_scale,
            lower_trust=options.get("lower_trust", law.lower_trust),
        )
    try:
        return base.replace(**overrides)
    except InvalidOption as exc:  # the reader's ranges are tighter; kept as a safety net
        raise reader.fail(f"solver.{exc.field}", exc.expected) from exc


def options_dict(options: SolveOptions) -> dict[str, Any]:
    """The run's options as plain data (the damping law as its fields)."""
    law = options.damping_law
    return {
        "tol_position": options.tol_position,
        "tol_orientation": options.tol_orientation,
        "max_iters": options.max_iters,
        "restarts": options.restarts,
        "seed": options.seed,
        "time_budget": options.time_budget,
        "alpha": options.alpha,
        "beta": options.beta,
        "max_step": jsonable(options.max_step),
        "stall_window": options.stall_window,
        "solver": options.solver,
        "damping": options.damping,
        "damping_law": None if law is None else jsonable(vars(law)),
    }


def _read_max_step(reader: Reader, value) -> list[float] | bool:
    """``max_step = [metres, radians]`` or ``false``."""
    if value is False:
        return False
    vector = reader.vector(value, "solver.max_step", 2, "[metres, radians] or false")
    for i, v in enumerate(vector):
        reader.number(float(v), f"solver.max_step[{i}]", "solver.max_step")
    return vector.tolist()

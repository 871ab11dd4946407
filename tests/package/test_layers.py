"""The package's layers (docs/architecture.md): a module imports only from its own layer
or the layers below it. Checked on the source (AST), so a new import that crosses a layer
upward fails here, with the module and the import named."""

from __future__ import annotations

import ast
from pathlib import Path

import qpik

ROOT = Path(qpik.__file__).parent

#: The layers, lowest first. A folder of ``qpik/`` is one layer; the base (errors and
#: options) may be imported by every layer; the front doors (analysis, statics, plots, the
#: viewer, and the thin public paths robots and scene) sit with the applications.
BASE, CORE, MODEL, TASKS, DIFFIK, APPLICATIONS = range(6)
LAYERS = {
    "qpik.errors": BASE,
    "qpik.options": BASE,
    "qpik._engine": CORE,  # the compiled engine (C++; its sources in qpik/_cpp mirror the layers)
    "qpik.core": CORE,  # matrices only: linear algebra, the QP solvers, the cascade
    "qpik.model": MODEL,  # configuration, robot files, frames, Lie groups, scenes
    "qpik.tasks": TASKS,
    "qpik.limits": TASKS,
    "qpik.diffik": DIFFIK,  # IKSolver, the compiled step, mink compatibility
    "qpik.igm": APPLICATIONS,
    "qpik.batch": APPLICATIONS,
    "qpik.problem": APPLICATIONS,
    "qpik.cli": APPLICATIONS,
    "qpik.analysis": APPLICATIONS,
    "qpik.statics": APPLICATIONS,
    "qpik.plots": APPLICATIONS,
    "qpik.viewer": APPLICATIONS,
    "qpik.robots": APPLICATIONS,
    "qpik.scene": APPLICATIONS,
}
#: At most this many modules at the top of ``qpik/`` besides the layer folders.
TOP_MODULES = {"errors", "options", "analysis", "statics", "plots", "robots", "scene", "viewer"}


def layer_of(module: str) -> int:
    """The layer of ``qpik.x.y``: its own entry or its folder's."""
    parts = module.split(".")
    for end in range(len(parts), 1, -1):
        name = ".".join(parts[:end])
        if name in LAYERS:
            return LAYERS[name]
    raise AssertionError(f"{module} has no layer: add its folder to LAYERS")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path) -> set[str]:
    """The qpik modules a file imports (``from . import x`` counts as ``package.x``)."""
    module = module_name(path)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            if not name.startswith("qpik"):
                continue
            for alias in node.names:
                candidate = f"{name}.{alias.name}"
                is_module = (ROOT.parent / (candidate.replace(".", "/") + ".py")).exists() or (
                    ROOT.parent / candidate.replace(".", "/") / "__init__.py"
                ).exists()
                found.add(candidate if is_module else name)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("qpik"))
    return found


def test_no_module_imports_from_a_layer_above_its_own():
    violations = []
    for path in sorted(ROOT.rglob("*.py")):
        module = module_name(path)
        if module == "qpik":  # the package's front door re-exports every layer
            continue
        for target in imported_modules(path):
            if target != "qpik" and layer_of(target) > layer_of(module):
                violations.append(f"{module} (layer {layer_of(module)}) imports {target}")
    assert not violations, "\n".join(violations)


def test_the_core_imports_neither_mujoco_nor_mink():
    for path in sorted((ROOT / "core").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            for name in names:
                assert name.split(".")[0] not in ("mujoco", "mink"), f"{path.name}: {name}"


def test_every_module_has_a_layer_the_checker_can_read():
    """The map stays honest: every listed module exists."""
    for name in LAYERS:
        path = ROOT.parent / name.replace(".", "/")
        if name == "qpik._engine":  # compiled: its C++ sources sit in qpik/_cpp
            assert (ROOT / "_cpp" / "module.cpp").exists(), name
            continue
        assert path.with_suffix(".py").exists() or (path / "__init__.py").exists(), name


def test_the_top_of_the_package_holds_only_the_front_doors_and_the_base():
    top = {p.stem for p in ROOT.glob("*.py") if p.stem != "__init__"}
    top |= {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    folders = {"core", "model", "tasks", "limits", "diffik", "igm", "batch", "problem", "cli"}
    assert top - folders <= TOP_MODULES, sorted(top - folders - TOP_MODULES)
    assert len(TOP_MODULES) <= 8


def test_no_module_imports_another_modules_underscore_names():
    """Private names stay private: ``from x import _name`` only within one module's own
    package-private engine (``qpik._engine``)."""
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    if alias.name.startswith("_") and alias.name != "__version__":
                        found.append(f"{module_name(path)}: from {node.module} import {alias.name}")
    assert not found, "\n".join(found)


def test_no_import_circles():
    """The graph of imports between qpik's modules (at any depth of a file, so imports
    inside functions count) has no cycle, inside a folder or across folders."""
    graph = {}
    for path in sorted(ROOT.rglob("*.py")):
        module = module_name(path)
        if module == "qpik":
            continue
        graph[module] = {t for t in imported_modules(path) if t != module and t != "qpik"}
    # a package's __init__ re-exports its modules: importing the package means the module
    # named there, so an edge to a package goes to the package's own file only
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt) :] + [nxt]))
            elif nxt in graph and not state.get(nxt):
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if not state.get(node):
            visit(node)
    assert not cycles, "\n".join(cycles)


def test_no_module_is_over_700_lines():
    """A module holds one idea; one over 700 lines holds several (split it by idea)."""
    long = {
        str(path.relative_to(ROOT)): n
        for path in ROOT.rglob("*.py")
        if (n := len(path.read_text().splitlines())) > 700
    }
    assert not long, long


def test_import_qpik_loads_nothing_heavy_beyond_mujoco_and_mink():
    """``import qpik`` stays light (issue 20: at most 0.2 s over ``import mujoco, mink``):
    in a fresh process it loads only qpik's own modules and the standard library beyond
    what ``import mujoco, mink`` loads. Heavy optional parts (scipy.spatial for support
    polygons, matplotlib, viser, tqdm, ray) are imported where they are used."""
    import subprocess
    import sys

    code = (
        "import sys, mujoco, mink; before = set(sys.modules); import qpik; "
        "print(' '.join(sorted({m.split('.')[0] for m in set(sys.modules) - before})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    heavy = [m for m in out if m in {"scipy", "matplotlib", "viser", "tqdm", "ray", "pandas"}]
    assert not heavy, f"import qpik loads {heavy} beyond mujoco and mink: {out}"

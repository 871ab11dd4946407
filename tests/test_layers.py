"""The package's layers (docs/architecture.md): a module imports only from its own layer
or the layers below it. Checked on the source (AST), so a new import that crosses a layer
upward fails here, with the module and the import named."""

from __future__ import annotations

import ast
from pathlib import Path

import qpik

ROOT = Path(qpik.__file__).parent

#: Layer of each module, lowest first (a module not listed is an application, layer 5).
CORE, BASE, MODEL, TASKS, IK, APPLICATIONS = range(6)
LAYERS = {
    "qpik._engine": CORE,  # the compiled engine (C++; its submodules mirror the layers)
    "qpik.core": CORE,  # matrices only: the hierarchical QP, backends, damping
    "qpik.errors": BASE,  # typed errors (subclassing mink's) and the options object
    "qpik.options": BASE,
    "qpik.checks": BASE,  # input checks of every entry point (imports errors and options)
    "qpik.model": MODEL,  # configuration, robots, frames, rotations, chain kinematics
    "qpik.configuration": MODEL,
    "qpik.robots": MODEL,
    "qpik.robot_files": MODEL,
    "qpik.scene": MODEL,
    "qpik.tasks": TASKS,  # tasks and limits turn a configuration into rows
    "qpik.limits": TASKS,
    "qpik.analysis": TASKS,  # Jacobian analysis and statics sit beside them
    "qpik.statics": TASKS,
    "qpik.hierarchy": IK,  # the IK layer: stacks become QPs, IKSolver
    "qpik._fused": IK,
    "qpik.mink_api": IK,
    "qpik.qp": IK,
}


def layer_of(module: str) -> int:
    """The layer of ``qpik.x.y``: its own entry or its package's, else applications."""
    parts = module.split(".")
    for end in range(len(parts), 1, -1):
        name = ".".join(parts[:end])
        if name in LAYERS:
            return LAYERS[name]
    return APPLICATIONS


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

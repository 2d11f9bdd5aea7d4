"""The package's layer order (docs: ../shared/ARCHITECTURE.md, "Layers"), checked on the source.

Every ``import`` and ``from ... import`` (module level and inside functions) of every module
under ``src/sensorless`` is parsed with :mod:`ast`; a module may import only modules of its
own layer or below. Bottom to top:

    0  errors, io                                  typed errors, atomic writes, version info
    1  robot, parameters, model_checks, export,    Pinocchio model, parameter conventions,
       urdf_patch, robot_paths, xacro_expand,      URDF export, confined file references, xacro,
       robots (the registry of named robots)       the names load_robot accepts
    2  data                                        Trajectory, readers, validation, filtering
    3  regressor                                   terms, row maps, compression
    4  identification, robots.dvrk_psm             solve; robots authored in code (dVRK PSM; the registry
                                                   names its builder by dotted path, imported on load)
    5  learning, control, estimation, excitation,  users of an identified model; ``report``
       actuator, estimators, report, realtime      (plots, tables, HTML) is used by experiments
    6  simulation                                  MuJoCo scenes and scenario scripts
    7  experiments, example_data                   the papers' studies; data for the documented commands
    8  cli, benchmarks, demo                       commands, speed/scale/accuracy benchmarks, the demo
"""

from __future__ import annotations

import ast
from pathlib import Path

from typer.testing import CliRunner

SRC = Path(__file__).resolve().parents[1] / "src" / "sensorless"

LAYERS = {
    "errors": 0, "io": 0, "_outdir": 0, "__version__": 0, "_lazy": 0,
    "robot": 1, "parameters": 1, "model_checks": 1, "export": 1, "urdf_patch": 1,
    "robot_paths": 1, "xacro_expand": 1, "_xacro_worker": 1,
    "data": 2,
    "regressor": 3,
    "robots": 1, "robots.dvrk_psm": 4,  # the registry; a robot authored in code on the transmission module
    "identification": 4,
    "learning": 5, "control": 5, "estimation": 5, "excitation": 5, "actuator": 5, "estimators": 5, "report": 5,
    "realtime": 5,
    "simulation": 6,
    "experiments": 7, "example_data": 7,
    "cli": 8, "benchmarks": 8, "demo": 8,
}
#: modules allowed to import ``sensorless.simulation`` / ``sensorless.experiments``
APPLICATION = {"simulation", "experiments", "example_data", "cli", "benchmarks", "demo"}

#: Known upward imports, each in a file another change owns; remove an entry when it is fixed.
ALLOWED_UPWARD = {
}


def _module_name(path: Path, root: Path = SRC) -> tuple[str, list[str]]:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    package = parts[:-1]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts), package


def _imports(path: Path, root: Path = SRC) -> list[tuple[str, int]]:
    """Absolute names of the ``sensorless`` modules ``path`` imports, with line numbers."""
    _, package = _module_name(path, root)
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                if node.module:
                    out.append((".".join(base + [node.module]), node.lineno))
                else:  # from . import a, b
                    out += [(".".join(base + [a.name]), node.lineno) for a in node.names]
            else:
                out.append((node.module, node.lineno))
    return [(n, line) for n, line in out if n == "sensorless" or n.startswith("sensorless.")]


def _top(name: str) -> str | None:
    """The LAYERS key of a module: its top-level module, or a sub-module given its own layer."""
    parts = name.split(".")
    if len(parts) > 2 and ".".join(parts[1:3]) in LAYERS:
        return ".".join(parts[1:3])
    return parts[1] if len(parts) > 1 else None


def _edges():
    for path in sorted(SRC.rglob("*.py")):
        mod, _ = _module_name(path)
        for target, line in _imports(path):
            yield mod, target, f"{path.relative_to(SRC.parent)}:{line}"


def test_every_top_level_module_has_a_layer():
    names = {p.stem for p in SRC.glob("*.py") if p.stem != "__init__"} | {p.name for p in SRC.iterdir() if (p / "__init__.py").exists()}
    assert names - set(LAYERS) == set(), "give each new top-level module or package a layer in LAYERS"


def test_imports_point_down_the_layers():
    bad = []
    for mod, target, where in _edges():
        src, dst = _top(mod), _top(target)
        if src is None or dst is None or src == dst:
            continue
        if LAYERS[dst] > LAYERS[src] and (mod, target) not in ALLOWED_UPWARD:
            bad.append(f"{where}: {mod} (layer {LAYERS[src]}) imports {target} (layer {LAYERS[dst]})")
    assert bad == [], "\n".join(bad)


def test_no_library_module_imports_simulation_or_experiments():
    bad = [
        f"{where}: {mod} imports {target}"
        for mod, target, where in _edges()
        if _top(target) in ("simulation", "experiments") and _top(mod) not in APPLICATION
    ]
    assert bad == [], "\n".join(bad)


def test_the_checker_sees_relative_and_function_level_imports(tmp_path):
    """``from ..x import y`` inside a function, ``from . import z`` and absolute imports resolve."""
    root = tmp_path / "sensorless"
    (root / "data").mkdir(parents=True)
    f = root / "data" / "reader.py"
    f.write_text("import numpy\nimport sensorless.robot\n\ndef g():\n"
                 "    from ..simulation.quadruped import simulate\n    from . import trajectory\n")
    assert _imports(f, root) == [("sensorless.robot", 2), ("sensorless.simulation.quadruped", 5),
                                 ("sensorless.data.trajectory", 6)]


def test_version_option_prints_the_package_version():
    import sensorless
    from sensorless.cli import app

    res = CliRunner().invoke(app, ["--version"])
    assert res.exit_code == 0, res.output
    assert res.output.strip() == f"sensorless {sensorless.__version__}"


#: modules that are data tables rather than code (none today); they may exceed the limit
DATA_TABLES: frozenset[str] = frozenset()


def test_no_module_over_500_lines():
    """Issue #15: a module past 500 lines is split by concept (data tables excepted)."""
    long = {str(p.relative_to(SRC)): n for p in SRC.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 500 and str(p.relative_to(SRC)) not in DATA_TABLES}
    assert not long, f"split these modules: {long}"

"""The package's layer order and structural rules, checked on the source; docs/architecture.md
explains them ("Layers", "Structural rules") and its layer table is ``LAYERS`` (a test keeps them equal).

Every ``import`` and ``from ... import`` (module level and inside functions) of every module
under ``src/sensorless`` is parsed with :mod:`ast`; a module may import only modules of its
own layer or below (0 errors, io … 8 cli). The simulations, studies, benchmarks, documentation data and
demo are the separate package ``sensorless_studies`` (``studies/``), which the library never imports (its own
layers: ``studies/tests/test_studies_layers.py``).
"""

from __future__ import annotations

import ast
from pathlib import Path

from structural_rules import (import_cycles, imported, layer_violations, modules, private_imports,
                              imports_of_tests, shims, unlayered)
from typer.testing import CliRunner

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src" / "sensorless"
STUDIES = TESTS.parent / "studies" / "src" / "sensorless_studies"

LAYERS = {
    "errors": 0, "io": 0, "outdir": 0, "lazy": 0, "__version__": 0,  # ``from .. import __version__``: the package's own
    "robot": 1, "parameters": 1, "model_checks": 1, "export": 1, "export_mjcf": 1, "urdf_patch": 1,
    "robot_paths": 1, "xacro_expand": 1, "_xacro_worker": 1,
    "data": 2, "testing": 2,
    "regressor": 3,
    "robots": 1, "robots.dvrk_psm": 4,  # the registry; a robot authored in code on the transmission module
    "identification": 4,
    "learning": 5, "control": 5, "estimation": 5, "excitation": 5, "actuator": 5, "torque_models": 5, "report": 5,
    "realtime": 5,
    "run": 6,
    "cli": 8, "__main__": 8,
}

#: Known upward imports, each in a file another change owns; remove an entry when it is fixed.
ALLOWED_UPWARD = {
}


def test_the_architecture_doc_lists_these_layers():
    """docs/architecture.md's layer table names every module of ``LAYERS`` at its layer."""
    import re

    doc = (SRC.parents[1] / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| (\d) \| ([^|]+) \|", doc, flags=re.M)
    table = {name: int(layer) for layer, cell in rows for name in re.findall(r"`([\w.]+)`", cell)}
    assert table == {name: layer for name, layer in LAYERS.items() if name != "__version__"}


def test_every_top_level_module_has_a_layer():
    assert unlayered(SRC, LAYERS) == set(), "give each new top-level module or package a layer in LAYERS"


def test_imports_point_down_the_layers():
    bad = layer_violations(SRC, LAYERS, ALLOWED_UPWARD)
    assert bad == [], "\n".join(bad)


def _imported_names(path: Path) -> list[tuple[str, int]]:
    """Every absolute module name ``path`` imports (any package), with line numbers."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            out.append((node.module, node.lineno))
    return out


def test_the_library_never_imports_the_studies():
    """src/sensorless holds no study: no import of ``sensorless_studies`` (nor a name for it in importlib
    calls), and none of the studies' packages left in the library."""
    bad = [f"{p.relative_to(SRC.parent)}:{line}: imports {name}" for p in sorted(SRC.rglob("*.py"))
           for name, line in _imported_names(p) if name.split(".")[0] == "sensorless_studies"]
    bad += [f"{p.relative_to(SRC.parent)}: names sensorless_studies" for p in sorted(SRC.rglob("*.py"))
            if "sensorless_studies" in p.read_text(encoding="utf-8")]
    assert bad == [], "\n".join(bad)
    left = [n for n in ("simulation", "experiments", "benchmarks", "example_data", "demo")
            if (SRC / n).exists() or (SRC / f"{n}.py").exists()]
    assert left == [], f"studies inside the library: {left}"


def test_the_checker_sees_relative_and_function_level_imports(tmp_path):
    """``from ..x import y`` inside a function, ``from . import z`` and absolute imports resolve."""
    root = tmp_path / "sensorless"
    (root / "data").mkdir(parents=True)
    f = root / "data" / "reader.py"
    f.write_text("import numpy\nimport sensorless.robot\n\ndef g():\n"
                 "    from ..simulation.quadruped import simulate\n    from . import trajectory\n")
    (root / "data" / "trajectory.py").write_text("")
    (root / "simulation").mkdir()
    (root / "simulation" / "quadruped.py").write_text("def simulate():\n    pass\n")
    assert list(imported(f, modules(root), ["sensorless", "data"])) == [
        ("sensorless.robot", None, 2), ("sensorless.simulation.quadruped", "simulate", 5),
        ("sensorless.data.trajectory", None, 6)]


def test_version_option_prints_the_package_version():
    import sensorless
    from sensorless.cli import app

    res = CliRunner().invoke(app, ["--version"])
    assert res.exit_code == 0, res.output
    assert res.output.strip() == f"sensorless {sensorless.__version__}"


# ---- structural rules (docs/architecture.md, "Structural rules"; the checkers: tests/structural_rules.py) ----
# Boundaries are drawn by concept, not by size: no module imports another module's private names,
# the modules form no import cycle, and no module is a re-export or deprecation shim.

def test_no_module_imports_another_modules_private_names():
    bad = private_imports(SRC)
    assert bad == [], "make the name public in its owner (drop the underscore, add a docstring) or move it " \
                      "to the module that owns the concept:\n" + "\n".join(bad)


def test_no_import_cycles():
    bad = import_cycles(SRC)
    assert bad == [], "move the shared piece down into a module both can import:\n" + "\n".join(bad)


def test_no_reexport_or_deprecation_shims():
    bad = shims(SRC)
    assert bad == [], "import names from the module that defines them; delete deprecated names:\n" + "\n".join(bad)


def test_the_tests_import_no_private_name():
    """The tests use the public names of the library and of the studies, as their users do."""
    bad = imports_of_tests(TESTS, SRC, STUDIES)
    assert bad == [], "make the name public in its owner (drop the underscore, add a docstring):\n" + "\n".join(bad)


def test_the_structural_checks_find_each_kind_of_violation(tmp_path):
    """A small package with one violation of each rule: every checker names module, line and name."""
    root = tmp_path / "sensorless"
    (root / "data").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "data" / "__init__.py").write_text("from .a import f\n")
    (root / "data" / "a.py").write_text("def f():\n    from .b import g\n    return g\n\n_C = 1\n")
    (root / "data" / "b.py").write_text("import math\n\n\ndef g():\n    from sensorless.data.a import _C\n    return _C\n")
    (root / "data" / "_hidden.py").write_text("X = 1\n")
    (root / "data" / "c.py").write_text("from ._hidden import X\n\n\ndef h():\n    return X\n")
    (root / "old.py").write_text('"""Moved."""\nfrom .data.a import f\n\n__all__ = ["f"]\n')
    (root / "lazy.py").write_text("import warnings\n_MOVED = ('f',)\n\n\ndef __getattr__(name):\n"
                                  "    warnings.warn('gone', DeprecationWarning)\n")
    (root / "mixed.py").write_text("from .data.a import f\n\n__all__ = ['f', 'k']\n\n\ndef k():\n    return f\n")
    (root / "user.py").write_text("def u():\n    from .mixed import f\n    return f\n")
    private = private_imports(root)
    assert private == ["sensorless/data/b.py:5: sensorless.data.b imports private name _C from sensorless.data.a",
                       "sensorless/data/c.py:1: sensorless.data.c imports private module sensorless.data._hidden"
                       " (name X)"] or sorted(private) == sorted(
        ["sensorless/data/b.py:5: sensorless.data.b imports private name _C from sensorless.data.a",
         "sensorless/data/c.py:1: sensorless.data.c imports private module sensorless.data._hidden (name X)"])
    (cycle,) = import_cycles(root)
    assert "sensorless.data.a ↔ sensorless.data.b" in cycle and "sensorless/data/a.py:2:" in cycle \
        and "sensorless/data/b.py:5:" in cycle
    found = "\n".join(shims(root))
    assert "sensorless/old.py:1: sensorless.old only re-imports names (f)" in found
    assert "sensorless/lazy.py:5: sensorless.lazy defines a module __getattr__" in found
    assert "sensorless/lazy.py:2: sensorless.lazy keeps a _MOVED table" in found
    assert "sensorless/lazy.py:6: sensorless.lazy has a deprecation path (DeprecationWarning)" in found
    assert "sensorless/mixed.py:3: sensorless.mixed re-exports f (imported on line 1) in __all__" in found
    assert "sensorless/user.py:2: sensorless.user imports f through sensorless.mixed, which only imports it" in found
    assert "data/__init__" not in found  # a package __init__ exporting its submodules' names is its API


def test_a_using_package_and_the_tests_see_only_public_names(tmp_path):
    """The checkers follow imports into a library another package uses, and from test files."""
    lib, user, tests = tmp_path / "lib" / "sensorless", tmp_path / "user" / "sensorless_studies", tmp_path / "tests"
    for d in (lib / "data", user / "sim", user / "cli", tests):
        d.mkdir(parents=True)
    (lib / "__init__.py").write_text("")
    (lib / "data" / "__init__.py").write_text("")
    (lib / "data" / "a.py").write_text("def f():\n    pass\n\n\ndef _g():\n    pass\n")
    (lib / "data" / "_b.py").write_text("X = 1\n")
    (user / "__init__.py").write_text("")
    (user / "sim" / "__init__.py").write_text("")
    (user / "sim" / "run.py").write_text("from sensorless.data.a import f, _g\n\n\ndef r():\n"
                                         "    from sensorless.data import _b\n    from ..cli import main\n")
    (user / "cli" / "__init__.py").write_text("")
    (user / "cli" / "main.py").write_text("from sensorless_studies.sim.run import r\n")
    (tests / "test_x.py").write_text("from sensorless.data.a import _g as g\nfrom sensorless_studies.sim.run import r\n")
    assert private_imports(user, lib) == [
        "sensorless_studies/sim/run.py:1: sensorless_studies.sim.run imports private name _g from sensorless.data.a",
        "sensorless_studies/sim/run.py:5: sensorless_studies.sim.run imports private module sensorless.data._b"]
    assert imports_of_tests(tests, lib, user) == [
        "tests/test_x.py:1: tests.test_x imports private name _g from sensorless.data.a"]
    assert layer_violations(user, {"sim": 0, "cli": 1}) == [
        "sensorless_studies/sim/run.py:6: sensorless_studies.sim.run (layer 0) imports sensorless_studies.cli.main (layer 1)"]
    assert unlayered(user, {"sim": 0}) == {"cli"}

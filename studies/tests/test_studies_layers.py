"""The studies package's layer order, checked on its source (the library's: tests/test_layers.py).

Every import (module level and inside functions) of every module under ``studies/src/sensorless_studies``
is parsed with :mod:`ast`; a module may import only modules of its own layer or below, and any public
module of the library ``sensorless`` (never a ``_private`` module of it). Bottom to top:

    0  simulation                MuJoCo scenes, simulated robots and logs with known ground truth
    1  experiments               the papers' studies
    2  example_data              the data of the documented commands (some written by a study's code)
    3  benchmarks, demo          speed, scale and accuracy benchmarks; the end-to-end demo
    4  cli                       the commands, added to ``sensorless`` through entry points
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

STUDIES = Path(__file__).resolve().parents[1]
SRC = STUDIES / "src" / "sensorless_studies"

LAYERS = {"simulation": 0, "experiments": 1, "example_data": 2, "benchmarks": 3, "demo": 3, "cli": 4}


def _imports(path: Path) -> list[tuple[str, int]]:
    """Absolute names of the modules ``path`` imports (relative imports resolved), with line numbers."""
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    package = parts[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                if node.module:
                    out.append((".".join(base + [node.module]), node.lineno))
                else:
                    out += [(".".join(base + [a.name]), node.lineno) for a in node.names]
            else:
                out.append((node.module, node.lineno))
    return out


def _top(name: str) -> str | None:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else None


def test_every_study_module_has_a_layer():
    names = {p.stem for p in SRC.glob("*.py") if p.stem != "__init__"} | {
        p.name for p in SRC.iterdir() if (p / "__init__.py").exists()}
    assert names - set(LAYERS) == set(), "give each new top-level module or package a layer in LAYERS"


def test_study_imports_point_down_the_layers():
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        src = _top(".".join(path.relative_to(SRC.parent).with_suffix("").parts))
        for name, line in _imports(path):
            if not name.startswith("sensorless_studies."):
                continue
            dst = _top(name)
            if src is not None and dst != src and LAYERS[dst] > LAYERS[src]:
                bad.append(f"{path.relative_to(STUDIES)}:{line}: {src} (layer {LAYERS[src]}) imports {name}")
    assert bad == [], "\n".join(bad)


def test_the_studies_import_no_private_library_module():
    """The studies use the library's public modules only (``sensorless._lazy`` and the like are its own)."""
    bad = [f"{p.relative_to(STUDIES)}:{line}: {name}" for p in sorted(SRC.rglob("*.py"))
           for name, line in _imports(p)
           if name.split(".")[0] == "sensorless" and any(part.startswith("_") for part in name.split(".")[1:])]
    assert bad == [], "\n".join(bad)


def test_every_study_command_is_an_entry_point_the_library_lists():
    """studies/pyproject.toml registers exactly the library's STUDY_COMMANDS, each a typer app."""
    import importlib

    import typer

    from sensorless.cli.plugins import GROUP, STUDY_COMMANDS

    eps = tomllib.loads((STUDIES / "pyproject.toml").read_text())["project"]["entry-points"][GROUP]
    assert set(eps) == set(STUDY_COMMANDS)
    for name, target in eps.items():
        module, attr = target.split(":")
        assert isinstance(getattr(importlib.import_module(module), attr), typer.Typer), name

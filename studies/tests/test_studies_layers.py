"""The studies package's layer order and structural rules, checked on its source with the library's
checkers (``tests/structural_rules.py``; the library's own: tests/test_layers.py).

Every import (module level and inside functions) of every module under ``studies/src/sensorless_studies``
is parsed with :mod:`ast`; a module may import only modules of its own layer or below, and only the public
names and modules of the library ``sensorless``. Bottom to top:

    0  simulation                MuJoCo scenes, simulated robots and logs with known ground truth
    1  experiments               the papers' studies
    2  example_data              the data of the documented commands (some written by a study's code)
    3  benchmarks, demo          speed, scale and accuracy benchmarks; the end-to-end demo
    4  cli                       the commands, added to ``sensorless`` through entry points

As in the library: no module imports another module's ``_private`` names, the modules form no import
cycle, no module is a re-export shim, and the studies' tests import no private name either.
"""

from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

STUDIES = Path(__file__).resolve().parents[1]
SRC = STUDIES / "src" / "sensorless_studies"
LIBRARY = STUDIES.parent / "src" / "sensorless"

LAYERS = {"simulation": 0, "experiments": 1, "example_data": 2, "benchmarks": 3, "demo": 3, "cli": 4}


def _structural_rules():
    """The library tests' checker module (``tests/`` is not a package the studies' tests can import)."""
    spec = importlib.util.spec_from_file_location(
        "sensorless_structural_rules", STUDIES.parent / "tests" / "structural_rules.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


rules = _structural_rules()


def test_every_study_module_has_a_layer():
    assert rules.unlayered(SRC, LAYERS) == set(), "give each new top-level module or package a layer in LAYERS"


def test_study_imports_point_down_the_layers():
    bad = rules.layer_violations(SRC, LAYERS)
    assert bad == [], "\n".join(bad)


def test_the_studies_use_only_public_names():
    """No study imports another study module's private name, nor a private name or module of the library."""
    bad = rules.private_imports(SRC, LIBRARY)
    assert bad == [], "make the name public in its owner (drop the underscore, add a docstring) or move it " \
                      "to the module that owns the concept:\n" + "\n".join(bad)


def test_the_studies_have_no_import_cycles():
    bad = rules.import_cycles(SRC)
    assert bad == [], "move the shared piece into the module that owns the concept:\n" + "\n".join(bad)


def test_the_studies_have_no_reexport_shims():
    bad = rules.shims(SRC, LIBRARY)
    assert bad == [], "import names from the module that defines them:\n" + "\n".join(bad)


def test_the_studies_tests_import_no_private_name():
    bad = rules.imports_of_tests(STUDIES / "tests", SRC, LIBRARY)
    assert bad == [], "make the name public in its owner (drop the underscore, add a docstring):\n" + "\n".join(bad)


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

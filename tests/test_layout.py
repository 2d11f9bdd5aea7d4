"""Tests findable by module: the tests of a library module are in a file whose name can be guessed.

The scheme (flat, one name per module; the prefix plays the role of a folder):

* ``sensorless/<pkg>/<mod>.py`` → ``tests/test_<pkg>_<mod>.py`` or ``tests/test_<pkg>_<mod>_<aspect>.py``
  (``sensorless/data/readers.py`` → ``tests/test_data_readers*.py``); a top-level module
  ``sensorless/<mod>.py`` → ``tests/test_<mod>[_<aspect>].py``;
* a helper named after the module of its package that imports it shares that module's file
  (``payload_fit``, ``payload_model`` → ``test_identification_payload*.py``);
* a module without a file of its own is exercised by one of its subpackage's files
  ``tests/test_<pkg>[_*].py`` (which imports it or names ``sensorless.<pkg>.<mod>``), so
  ``ls tests/test_<pkg>*`` and a grep find it;
* a CLI module is tested by the files that run its command (``["payload", ...]``);
* otherwise the module is in :data:`EXEMPT`, with the file that tests it and why (a private back end, a
  helper tested through the module that uses it, a figure tested with its command), or is a CLI helper every
  command uses (:data:`CLI_SHARED`).

Conversely every test file is named after a library module or subpackage, or is one of the
project-wide tests (:data:`PROJECT_WIDE`) or a study's test (:data:`STUDIES`).
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src" / "sensorless"

# module (path under src/sensorless, no suffix) -> (test file that exercises it, why it has no file of its own)
EXEMPT = {
    "__main__": ("test_speed.py", "the executable's entry point (its GC thresholds)"),
    "lazy": ("test_speed.py", "private PEP 562 helper of every package's __init__; its effect (nothing heavy "
                               "loaded by `import sensorless.cli`) is the start-up test"),
    "outdir": ("test_io.py", "private back end of sensorless.io.atomic_output_dir (manifest, lock, swap)"),
    "_xacro_worker": ("test_xacro_expand.py", "child process of sensorless.xacro_expand"),
    "model_checks": ("test_hardening.py", "issue-12 file: bad URDF values are one-line RobotModelErrors"),
    "data/gains": ("test_friction_gains.py", "issue-17 file (gains maps, drive gains from a pair)"),
    "data/integral_filter": ("test_regressor_integral.py", "the filter of the acceleration-free regressor"),
    "data/periodicity": ("test_identification_lmi.py", "period detection of the averaged-period validation"),
    "data/arrays": ("test_data.py", "the NPZ/HDF5 reader behind read_trajectory (its NPZ and HDF5 tests)"),
    "data/bench_log": ("test_cli_friction.py", "the friction command's bench-log reader"),
    "data/containers": ("test_data_limits.py", "declared NPZ/HDF5 sizes checked before reading"),
    "estimation/monitored": ("test_realtime_monitor.py", "the offline reference the stream monitor is compared to"),
    "identification/drive_gains": ("test_friction_gains.py", "issue-17 file: drive gains from a pair within 2 %"),
    "identification/fleet": ("test_regressor_distributed.py", "fleet identification on the distributed fold"),
    "identification/identifiability": ("test_regressor_contact.py", "identifiable directions under contact"),
    "identification/weights": ("test_defaults.py", "issue-13 regressions (lmi with weights='auto')"),
    "identification/result": ("test_identification_identify.py", "the result object identify() returns"),
    "identification/runaway": ("test_identification_verdicts.py", "its 'runaway guard' section"),
    "identification/uncertainty": ("test_hardening.py", "issue-12 file: relative std and joint motion"),
    "regressor/friction_columns": ("test_identification_friction.py", "the friction law's regressor columns"),
    "report/excitation_plot": ("test_excitation_limits.py", "the excite command's figure"),
    "report/force_plot": ("test_estimation_force.py", "the estimate-force figure"),
    "report/monitor_plot": ("test_estimation_collision.py", "the monitor figure"),
    "report/friction_bench_plot": ("test_cli_friction.py", "the friction command's figure"),
    "report/plot_process": ("test_cli_identify_e2e.py", "the figure process of identify"),
    "report/tables": ("test_cli_identify.py", "the console tables identify prints"),
    "cli/applied_model": ("test_realtime_monitor.py", "the robot and model that predict/monitor/stream apply"),
    "cli/blas": ("test_speed.py", "BLAS threads per command"),
    "cli/startup": ("test_speed.py", "NumPy modules deferred before SciPy's import, for every command"),
}
# CLI modules that only wrap studies (benchmark/experiment commands): they move with the studies
# CLI helpers shared by every command: exercised by every CLI test, the error-language table first
CLI_SHARED = {"cli/common", "cli/console", "cli/flags", "cli/channel_options", "cli/logs"}

PROJECT_WIDE = {
    "test_layers.py", "test_layout.py",  # structure
    "test_docs_api.py", "test_docs_logs.py", "test_docs_run.py", "test_doc_figures.py", "test_doc_drive_gains.py",
    "test_current_example.py",  # the docs run as printed
    "test_defaults.py", "test_hardening.py", "test_hardening_service.py", "test_corrupt_inputs.py",
    "test_friction_gains.py",  # issue regressions
    "test_speed.py", "test_realdata_kuka.py",
}
STUDIES = re.compile(r"test_(.*study.*|mujoco_scene|hopping_leg|example.*|benchmark_peers|fuzz|rotations)\.py")


@cache
def library_modules() -> tuple[str, ...]:
    out = []
    for p in sorted(SRC.rglob("*.py")):
        rel = p.relative_to(SRC).with_suffix("").as_posix()
        if rel.endswith("__init__"):
            continue
        out.append(rel)
    return tuple(out)


@cache
def files_in_tests() -> tuple[str, ...]:
    return tuple(sorted(p.name for p in TESTS.glob("test_*.py")))


def key(module: str) -> str:
    return module.replace("/", "_").lstrip("_")


def own_files(module: str) -> list[str]:
    """``test_<key>.py`` and ``test_<key>_<aspect>.py``, an aspect that is not itself another module."""
    keys = {key(m) for m in library_modules()}
    k = key(module)
    return [f for f in files_in_tests() if f == f"test_{k}.py" or (f.startswith(f"test_{k}_") and f[5:-3] not in keys)]


def _top_level_names(path: Path) -> set[str]:
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    return names


@cache
def package_exports(package: str) -> dict[str, str]:
    """Name -> defining submodule of a package's ``__init__`` (read, not imported): its ``from .mod import``
    lines (``*`` included) and the lazy maps of :func:`sensorless._lazy.lazy_exports` (``{"Name": ".mod"}``,
    ``dict.fromkeys([...], ".mod")``)."""
    init = SRC.parent / package.replace(".", "/") / "__init__.py"
    tree = ast.parse(init.read_text())
    lists = {t.id: node.value for node in tree.body if isinstance(node, ast.Assign)
             for t in node.targets if isinstance(t, ast.Name) and isinstance(node.value, (ast.List, ast.Tuple))}
    out: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
            target = f"{package}.{node.module}"
            for a in node.names:
                src = SRC.parent / target.replace(".", "/")
                if a.name == "*" and src.with_suffix(".py").exists():
                    out.update(dict.fromkeys(_top_level_names(src.with_suffix(".py")), target))
                else:
                    out[a.asname or a.name] = target
        elif isinstance(node, ast.Dict):
            for k, v in zip(node.keys, node.values):
                if isinstance(k, ast.Constant) and isinstance(v, ast.Constant) and str(v.value).startswith("."):
                    out[k.value] = package + v.value
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "fromkeys"
              and len(node.args) == 2 and isinstance(node.args[1], ast.Constant)):
            keys = lists.get(node.args[0].id) if isinstance(node.args[0], ast.Name) else node.args[0]
            for k in getattr(keys, "elts", []):
                if isinstance(k, ast.Constant):
                    out[k.value] = package + node.args[1].value
    return out


def _resolve(module: str, name: str) -> str:
    """The module that defines ``name`` of ``from module import name``: a submodule, the module
    itself, or (from a package's exports) the submodule the package takes it from."""
    path = SRC.parent / module.replace(".", "/")
    if (path / f"{name}.py").exists() or (path / name / "__init__.py").exists():
        return f"{module}.{name}"
    if not (path / "__init__.py").exists():
        return module
    return package_exports(module).get(name, module)


@cache
def exercised(test_file: str) -> frozenset[str]:
    """Dotted library modules a test file imports (names resolved to their defining module) or names."""
    text = (TESTS / test_file).read_text()
    mods = set(re.findall(r"\bsensorless(?:\.\w+)+", text))
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and node.module.startswith("sensorless."):
            mods.update(_resolve(node.module, a.name) for a in node.names)
    return frozenset(mods)


@cache
def commands_run(test_file: str) -> frozenset[str]:
    """First elements of list literals: the commands a file passes to the CLI runner."""
    tree = ast.parse((TESTS / test_file).read_text())
    return frozenset(n.elts[0].value for n in ast.walk(tree) if isinstance(n, ast.List) and n.elts
                     and isinstance(n.elts[0], ast.Constant) and isinstance(n.elts[0].value, str))


@cache
def cli_commands() -> dict[str, set[str]]:
    """CLI module (``cli/<mod>``) -> the top-level commands it registers."""
    from sensorless.cli import app

    out: dict[str, set[str]] = {}
    for c in app.registered_commands:
        name = c.name or c.callback.__name__.replace("_", "-")
        out.setdefault(c.callback.__module__.removeprefix("sensorless.").replace(".", "/"), set()).add(name)
    return out


def imports(owner: str, leaf: str) -> bool:
    """Whether module ``owner`` imports its sibling ``leaf`` (the helper is part of it)."""
    for node in ast.walk(ast.parse((SRC / f"{owner}.py").read_text())):
        if isinstance(node, ast.ImportFrom) and ((node.module or "").split(".")[-1] == leaf
                                                 or any(a.name == leaf for a in node.names)):
            return True
    return False


#: one file per entry, registered in the package's ``__init__`` (docs/architecture.md, "Registries")
REGISTRY_PACKAGES = {"data/formats", "regressor/joint_terms"}


def covered(module: str) -> bool:
    if own_files(module):
        return True
    pkg, _, leaf = module.rpartition("/")
    modules = set(library_modules())
    parents = [f"{pkg}/{leaf[:i]}".lstrip("/") for i, ch in enumerate(leaf) if ch == "_" and i > 0]
    if any(p in modules and own_files(p) and imports(p, leaf) for p in parents):
        return True
    dotted = "sensorless." + module.replace("/", ".")
    if pkg in REGISTRY_PACKAGES and f"test_{pkg.replace('/', '_')}.py" in files_in_tests() and imports(f"{pkg}/__init__", leaf):
        return True  # one entry of a registry package: the package's test file runs every entry it registers
    if pkg:
        prefix = "test_" + pkg.replace("/", "_")
        family = [f for f in files_in_tests() if f == f"{prefix}.py" or f.startswith(f"{prefix}_")]
        if any(dotted in exercised(f) for f in family):
            return True
    commands = cli_commands().get(module, set())
    return bool(commands) and any(commands & commands_run(f) for f in files_in_tests())


def test_every_library_module_has_a_test_file_under_a_guessable_name():
    missing = [m for m in library_modules()
               if not covered(m) and m not in EXEMPT and m not in CLI_SHARED]
    assert not missing, ("no tests/test_<subpackage>_<module>*.py (nor a subpackage file importing it) for "
                         + ", ".join(missing) + "; name the module's tests so, or add it to EXEMPT with the reason")


def test_exemptions_are_needed_and_point_to_files_that_exist():
    modules = set(library_modules())
    for module, (test_file, why) in EXEMPT.items():
        assert module in modules, f"EXEMPT lists {module}, which is no library module any more"
        assert not covered(module), f"{module} has tests under its own name now: drop it from EXEMPT"
        assert (TESTS / test_file).exists(), f"EXEMPT sends {module} to {test_file}, which does not exist"
        assert why
    for module in CLI_SHARED:
        assert module in modules, f"CLI_SHARED lists {module}, which is no library module any more"


def test_every_test_file_is_named_after_a_module_or_subpackage_or_is_project_wide():
    modules = library_modules()
    prefixes = {key(m) for m in modules} | {key(m.rpartition("/")[0]) for m in modules if "/" in m}
    strays = [f for f in files_in_tests() if f not in PROJECT_WIDE and not STUDIES.fullmatch(f)
              and not any(f == f"test_{p}.py" or f.startswith(f"test_{p}_") for p in prefixes)]
    assert not strays, ("test files named after neither a library module nor a subpackage: " + ", ".join(strays)
                        + " (rename to tests/test_<subpackage>_<module>[_aspect].py)")

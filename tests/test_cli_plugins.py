"""Commands from other packages (sensorless.cli.plugins): the studies join ``sensorless`` through the
entry-point group ``sensorless.commands``, loaded only when needed; without them the library CLI works
and says how to install them. The library's wheel holds no study."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest
from typer.testing import CliRunner

import sensorless.cli.plugins as plugins
from sensorless.cli import app

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="A group from another package.")


@app.command("hello")
def hello(name: str = typer.Option("world")) -> None:
    """Say hello."""
    print(f"hello {name}")


@app.command("bye")
def bye() -> None:
    """Say goodbye."""
    print("bye")
'''


@pytest.fixture
def entry_points(monkeypatch):
    """Set the entry points the CLI sees: ``{name: "module:attr"}``."""

    def use(points: dict) -> None:
        eps = {n: EntryPoint(n, v, plugins.GROUP) for n, v in points.items()}
        monkeypatch.setattr(plugins, "command_entry_points", lambda: eps)

    return use


def test_without_the_studies_their_commands_are_listed_and_say_how_to_install(entry_points):
    entry_points({})
    runner = CliRunner()
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0, res.output
    for name in plugins.STUDY_COMMANDS:
        assert name in res.output
    assert "not installed" in res.output
    for args in (["example", "--list"], ["benchmark", "speed", "--out", "x.json"], ["demo"], ["experiment", "--help"]):
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        assert f"sensorless {args[0]}" in res.output and "pip install -e studies" in res.output, res.output
    assert runner.invoke(app, ["--version"]).exit_code == 0
    assert runner.invoke(app, ["no-such-command"]).exit_code != 0


def test_an_entry_point_group_is_loaded_and_runs(tmp_path, monkeypatch, entry_points):
    (tmp_path / "other_pkg_cli.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    entry_points({"greet": "other_pkg_cli:app"})
    runner = CliRunner()
    res = runner.invoke(app, ["greet", "hello", "--name", "robot"])
    assert res.exit_code == 0, res.output
    assert "hello robot" in res.output
    res = runner.invoke(app, ["--help"])
    assert "greet" in res.output and "A group from another package." in res.output


def test_a_library_command_never_reads_the_entry_points(monkeypatch):
    def boom():
        raise AssertionError("entry points read for a library command")

    monkeypatch.setattr(plugins, "command_entry_points", boom)
    res = CliRunner().invoke(app, ["predict", "--help"])
    assert res.exit_code == 0, res.output


def test_an_entry_point_that_is_not_a_typer_app_is_refused(tmp_path, monkeypatch, entry_points):
    (tmp_path / "bad_pkg_cli.py").write_text("app = 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    entry_points({"bad": "bad_pkg_cli:app"})
    res = CliRunner().invoke(app, ["bad"])
    assert res.exit_code != 0
    assert isinstance(res.exception, TypeError) and "not a typer.Typer app" in str(res.exception)


def test_help_with_the_installed_commands_loads_no_heavy_package():
    """``sensorless --help`` lists every command (the studies' too, when installed) without NumPy & co."""
    code = ("import sys\nfrom sensorless.cli import app\ntry:\n    app(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = ['numpy', 'scipy', 'torch', 'matplotlib', 'cvxpy', 'pinocchio', 'mujoco', 'sensorless.data']\n"
            "print('HEAVY', [m for m in heavy if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"COLUMNS": "200", "PATH": "/usr/bin:/bin"}).stdout
    assert out.strip().endswith("HEAVY []"), out
    for name in plugins.STUDY_COMMANDS:
        assert f" {name} " in out


def test_the_library_wheel_holds_no_study(tmp_path):
    """Build the library's wheel from a copy of the source (nothing written into the repository) and
    list it: the library and its CLI, no simulation, experiment, benchmark, example data or demo."""
    pytest.importorskip("setuptools")
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "src" / "sensorless", src / "src" / "sensorless", ignore=shutil.ignore_patterns("__pycache__"))
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                          "-w", str(tmp_path / "dist"), str(src)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    (wheel,) = (tmp_path / "dist").glob("sensorless-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "sensorless/cli/__init__.py" in names and "sensorless/testing.py" in names
    studies = [n for n in names if n.startswith("sensorless_studies") or any(
        n.startswith(f"sensorless/{s}") for s in ("simulation", "experiments", "benchmarks", "example_data", "demo"))]
    assert studies == []
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert plugins.GROUP not in zipfile.ZipFile(wheel).read(entry_points).decode()

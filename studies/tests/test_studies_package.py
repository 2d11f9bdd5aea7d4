"""The studies package as a distribution: its wheel holds sensorless_studies (not the library), depends on
sensorless and declares its commands in the entry-point group the library reads; installed, they run
through ``sensorless`` under the documented names."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.cli.plugins import GROUP, STUDY_COMMANDS

STUDIES = Path(__file__).resolve().parents[1]


def test_the_studies_wheel_holds_the_studies_and_their_entry_points(tmp_path):
    pytest.importorskip("setuptools")
    src = tmp_path / "studies"
    src.mkdir()
    shutil.copy(STUDIES / "pyproject.toml", src / "pyproject.toml")
    shutil.copytree(STUDIES / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                          "-w", str(tmp_path / "dist"), str(src)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    (wheel,) = (tmp_path / "dist").glob("sensorless_studies-*.whl")
    z = zipfile.ZipFile(wheel)
    names = z.namelist()
    for module in ("cli/__init__.py", "simulation/quadruped.py", "experiments/contact_id.py",
                   "benchmarks/peers.py", "example_data/__init__.py", "demo.py"):
        assert f"sensorless_studies/{module}" in names, module
    assert not [n for n in names if n.startswith("sensorless/")]
    info = next(n for n in names if n.endswith(".dist-info/METADATA"))
    assert "Requires-Dist: sensorless" in z.read(info).decode()
    eps = configparser.ConfigParser()
    eps.read_string(z.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode())
    assert set(eps[GROUP]) == set(STUDY_COMMANDS)


@pytest.mark.parametrize("args, words", [
    (["example", "--list"], ["arm", "solo12-walk"]),
    (["experiment", "--help"], ["contact-id", "torque-control", "hybrid-force", "psm-identify"]),
    (["benchmark", "--help"], ["identify", "speed", "peers", "observer", "held-monitor", "stream", "friction-state",
                               "actuator-fit"]),
    (["demo", "--help"], ["--out", "--seed"]),
])
def test_the_installed_study_commands_run_under_their_documented_names(args, words):
    res = CliRunner().invoke(app, args, env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    for w in words:
        assert w in res.output, (args, w)


def test_a_benchmark_writes_outside_the_tracked_records(tmp_path, monkeypatch):
    """Default ``--out`` of every benchmark: sensorless-bench/NAME.json in the working directory, never a file
    under studies/benchmarks/results (the records the README's figures read)."""
    import typer

    from sensorless_studies.cli import benchmark_app

    group = typer.main.get_command(benchmark_app)
    defaults = {name: next(p.default for p in cmd.params if p.name == "out") for name, cmd in group.commands.items()}
    assert len(defaults) >= 15
    for name, out in defaults.items():
        assert Path(out).parts[0] == "sensorless-bench" and not Path(out).is_absolute(), (name, out)
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["benchmark", "actuator-fit", "--samples", "2000", "--repeats", "1"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "sensorless-bench" / "actuator_fit.json").is_file()

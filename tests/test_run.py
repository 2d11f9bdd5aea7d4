"""sensorless.run: the run object. Its defaults are the command's, the Python API gives the command's
numbers bitwise, a TOML file maps onto the same config, and messages name config fields (the CLI
writes them as its flags)."""

from __future__ import annotations

import dataclasses
import json
from enum import Enum

import pytest
from typer.main import get_command
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import OptionError
from sensorless.excitation import random_fourier
from sensorless.run import RunConfig, SolverConfig, identify_run, run_config_from_toml
from sensorless.run.config import config_fields
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()


@pytest.fixture(scope="module")
def logs(tmp_path_factory, ur5):
    """A perturbed UR5 (the truth), two different 6 s excitations at 100 Hz with noise: train and held out."""
    d = tmp_path_factory.mktemp("run")
    truth = perturbed_truth(ur5, rng=0)
    for name, seed in (("train", 1), ("test", 3)):
        traj = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, 6.0), noise_std=0.1, rng=seed + 1)
        write_npz(traj, d / f"{name}.npz")
    return d / "train.npz", d / "test.npz"


def _identify_command():
    return get_command(app).commands["identify"]


def test_config_defaults_are_the_command_defaults():
    """Every option of `sensorless identify` is a config field with the field's default, and the
    documented defaults hold (LMI, γ by cross-validation with the bracket search, the friction law)."""
    fields = config_fields()
    params = {p.name: p for p in _identify_command().params if p.name != "config"}
    assert set(params) == set(fields)
    for name, p in params.items():
        default = fields[name][1].default
        got = p.default
        if isinstance(got, Enum):
            got = got.value
        if isinstance(default, tuple):
            got = tuple(got or ())
        if fields[name][1].metadata["required"]:
            assert p.required, name
        else:
            assert got == default, (name, got, default)
    d = RunConfig()
    assert (d.solver.method, d.solver.gamma, d.solver.gamma_search) == ("lmi", "auto", "bracket")
    assert (d.solver.weights, d.solver.ellipsoids, d.solver.contain_prior) == ("auto", "auto", True)
    assert d.model.joint_terms == "fv,fc,stribeck,offset,armature"
    assert (d.model.coulomb_smoothing, d.model.stribeck_velocity, d.logs.rest) == ("auto", "auto", "auto")


def test_python_run_gives_the_command_numbers_bitwise(logs, tmp_path):
    train, test = logs
    r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(train), "--validate", str(test),
                            "--out", str(tmp_path / "cli")])
    assert r.exit_code == 0, r.output
    cli = json.loads((tmp_path / "cli" / "result.json").read_text())

    run = identify_run(RunConfig.from_options(robot="ur5", data=[train], validate=[test], out=tmp_path / "py"))
    assert run.save() == tmp_path / "py"  # execution.out, written atomically
    py = json.loads((tmp_path / "py" / "result.json").read_text())
    assert py["parameters"] == cli["parameters"] and py["validation"] == cli["validation"]
    assert py["settings"]["method"] == "lmi" and py["diagnostics"]["gamma"] == cli["diagnostics"]["gamma"]
    for doc in (py, cli):  # what differs is only how the run was started (and timings)
        doc["settings"].pop("config")
        doc.pop("versions", None)
        for key in [k for k in doc["diagnostics"] if "time" in k or "seconds" in k]:
            doc["diagnostics"].pop(key)
    assert py["base_parameters"] == cli["base_parameters"] and py["settings"] == cli["settings"]
    assert (tmp_path / "py" / "model.urdf").read_bytes() == (tmp_path / "cli" / "model.urdf").read_bytes()
    # the baseline and CAD rows of the held-out table; the fit predicts the other motion better than the prior
    v = py["validation"][str(test)]
    assert set(v) == {"lmi", "ols", "cad"} and v["lmi"]["mean_nrmse"] < v["cad"]["mean_nrmse"]
    assert [t for t, _ in run.tables] == [f"held-out {test.name}"]


def test_toml_maps_onto_the_config_flat_or_grouped(tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text('robot = "ur5"\ndata = "a.npz"\njoint-terms = "fv,offset"\n[solver]\ngamma = 0.01\n'
                   'method = "lmi"\n[execution]\nplot = false\n')
    c = run_config_from_toml(cfg, method="wls")
    assert c.model.robot == "ur5" and c.logs.data == ("a.npz",) and c.model.joint_terms == "fv,offset"
    assert c.solver == SolverConfig(method="wls", gamma=0.01) and c.execution.plot is False
    assert c.source == str(cfg) and dataclasses.replace(c.solver, gamma="auto") == SolverConfig(method="wls")


@pytest.mark.parametrize("text, key", [('metod = "lmi"\n', "metod"), ('[solver]\nrobot = "ur5"\n', "solver.robot"),
                                       ("trust_xacro = true\n", "trust_xacro")])
def test_toml_unknown_key_names_the_key_and_the_file(tmp_path, text, key):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    with pytest.raises(OptionError) as e:
        run_config_from_toml(cfg)
    assert str(cfg) in str(e.value) and key in str(e.value)


def test_messages_name_fields_and_the_command_writes_flags(logs, tmp_path):
    train, _ = logs
    with pytest.raises(OptionError, match=r"`solver\.gamma` must be a number or 'auto', got 'lots'"):
        identify_run(RunConfig.from_options(robot="ur5", data=[train], gamma="lots"))
    with pytest.raises(OptionError, match=r"`execution\.workers` needs `execution\.scheduler`"):
        identify_run(RunConfig.from_options(robot="ur5", data=[train], workers=2))
    for args, line in ((["--gamma", "lots"], "--gamma must be a number or 'auto', got 'lots'"),
                       (["--workers", "2"], "--workers needs --scheduler"),
                       (["--weights", str(tmp_path / "none.json")], "--weights must be auto, none or a JSON/CSV")):
        r = runner.invoke(app, ["identify", "--robot", "ur5", "--data", str(train), *args, "--out", str(tmp_path / "o")])
        assert r.exit_code == 2 and line in r.output and "solver." not in r.output and "execution." not in r.output
        assert not (tmp_path / "o").exists()

"""`sensorless benchmark peers`: the recipe, its truth, and a reduced run against the thresholds."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.benchmarks.peers import (
    DEFAULT_RECIPE,
    Recipe,
    cli_defaults,
    load_recipe,
    peer_case,
    run_peers,
)
from sensorless.cli import app
from sensorless.errors import OptionError
from sensorless.parameters import check_physical_consistency

DEFAULT_RECIPE_BODIES = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                         "wrist_2_joint", "wrist_3_joint")
RECIPE_FILE = Path(__file__).resolve().parents[1] / "benchmarks" / "peers.toml"


def test_recipe_file_is_the_built_in_recipe():
    assert load_recipe(RECIPE_FILE) == DEFAULT_RECIPE
    r = DEFAULT_RECIPE
    assert (r.robot, r.harmonics, r.base_freq) == ("ur5", 5, 0.1)
    p = r.perturbation
    assert (p.mass_log_sigma, p.com_sigma, p.moment_log_sigma, p.axis_sigma) == (0.1, 0.02, 0.2, 0.2)
    assert (r.cases["main"].noise, r.cases["hard"].noise, r.cases["hard"].train_samples) == (0.01, 0.05, 600)
    assert r.peers["main"] and r.peers["hard"] and "issue #13" in r.peers["source"]


def test_bad_recipe_is_an_option_error(tmp_path):
    (tmp_path / "r.toml").write_text('robot = "ur5"\n[cases.main]\nnoise = 0.01\n')  # no train_samples
    with pytest.raises(OptionError, match="r.toml"):
        load_recipe(tmp_path / "r.toml")
    (tmp_path / "s.toml").write_text("robot = [")
    with pytest.raises(OptionError, match="s.toml"):
        load_recipe(tmp_path / "s.toml")


def test_case_truth_is_physical_and_noise_is_as_specified(ur5):
    case = peer_case("hard", 3, ur5)
    P = case.truth.robot.inertial_parameters()
    assert all(r.consistent for r in check_physical_consistency(P, list(ur5.body_names)))
    assert not np.allclose(P, ur5.inertial_parameters())
    assert len(case.train) == 600
    clean = case.truth.torques(ur5.full_configuration(case.train.q), ur5.full_velocity(case.train.v),
                               ur5.full_velocity(case.train.a))
    np.testing.assert_allclose(case.noise_std, 0.05 * clean.std(axis=0))
    ratio = (case.train.tau - clean).std(axis=0) / case.noise_std
    assert np.all((ratio > 0.85) & (ratio < 1.15))
    # the held-out log is a different trajectory with noise-free torques
    assert not np.allclose(case.test.q[:100], case.train.q[:100])
    np.testing.assert_allclose(case.test.tau, case.truth.torques(ur5.full_configuration(case.test.q),
                                                                ur5.full_velocity(case.test.v),
                                                                ur5.full_velocity(case.test.a)))


def test_benchmark_uses_the_cli_defaults():
    d = cli_defaults()
    assert d["gamma"] == "auto" and d["weights"] == "auto" and d["ellipsoids"] == "auto" and d["contain_prior"]


def test_reduced_benchmark_meets_the_acceptance_thresholds():
    """Reduced run (one seed, the CLI-default LMI only) of both cases: at or below the peers'
    published figures, every body consistent."""
    res = run_peers(DEFAULT_RECIPE, seeds=(1,), variants=("lmi",))
    for name, limit in (("main", 0.53), ("hard", 8.0)):
        c = res["cases"][name]
        assert c["passed"], c
        assert c["lmi"]["mean_nrmse_percent"] <= limit and c["lmi"]["all_consistent"]


def test_cli_benchmark_peers_writes_json(tmp_path):
    out = tmp_path / "peers.json"
    r = CliRunner().invoke(app, ["benchmark", "peers", "--recipe", str(RECIPE_FILE), "--seeds", "2",
                                 "--cases", "hard", "--variants", "lmi", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    hard = doc["cases"]["hard"]
    assert set(hard) >= {"lmi", "passed", "acceptance_percent"}
    assert hard["passed"] and hard["lmi"]["runs"][0]["seed"] == 2
    assert set(hard["lmi"]["runs"][0]["consistent_bodies"]) == set(DEFAULT_RECIPE_BODIES)
    assert doc["peers"]["hard"] and doc["recipe"]["file"] == str(RECIPE_FILE)
    for bad, name in (["--seeds", "x"], "--seeds"), (["--variants", "rigeo"], "rigeo"):
        r = CliRunner().invoke(app, ["benchmark", "peers", *bad, "--out", str(tmp_path / "no.json")])
        assert r.exit_code == 2 and name in r.output and not (tmp_path / "no.json").exists()


def test_recipe_override_changes_the_case(ur5):
    short = Recipe(rate=200.0)
    assert np.isclose(peer_case("hard", 0, ur5, short).train.t[-1], 599 / 200.0)

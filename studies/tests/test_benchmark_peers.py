"""`sensorless benchmark peers`: the recipe, its truth, and a reduced run against the thresholds."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless_studies.benchmarks.peers import (
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
    assert r.speed == {"case": "hard", "defaults_seconds": 1.5, "ols_seconds": 1.0}


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
    assert getattr(d["method"], "value", d["method"]) == "lmi"  # the "lmi" variant runs `identify` with no flags


def test_reduced_benchmark_meets_the_acceptance_thresholds():
    """Reduced run (one seed, the CLI-default LMI only) of both cases: at or below the peers'
    published figures, every body consistent."""
    res = run_peers(DEFAULT_RECIPE, seeds=(1,), variants=("lmi",))
    for name, limit in (("main", 0.53), ("hard", 8.0)):
        c = res["cases"][name]
        assert c["passed"], c
        assert c["lmi"]["mean_nrmse_percent"] <= limit and c["lmi"]["all_consistent"]


def test_cli_benchmark_peers_writes_json_and_skips_absent_peers(tmp_path):
    """`identify` runs as a fresh process; peers whose venvs are absent are skipped with the reason, exit 0."""
    out = tmp_path / "peers.json"
    r = CliRunner().invoke(app, ["benchmark", "peers", "--recipe", str(RECIPE_FILE), "--seeds", "2",
                                 "--cases", "hard", "--variants", "lmi", "--against", "figaroh,rigeo",
                                 "--peer-venv", f"figaroh={tmp_path / 'none'}", "--peer-venv",
                                 f"rigeo={tmp_path / 'none2'}", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    hard = doc["cases"]["hard"]
    assert set(hard) >= {"lmi", "figaroh", "rigeo", "passed", "acceptance_percent"}
    assert hard["passed"] and hard["lmi"]["runs"][0]["seed"] == 2
    run = hard["lmi"]["runs"][0]
    assert set(run["consistent_bodies"]) == set(DEFAULT_RECIPE_BODIES)
    assert run["seconds"] > 0 and run["exit_seconds"] >= run["seconds"] and "--method" not in run["command"]
    for peer, venv in (("figaroh", "none"), ("rigeo", "none2")):
        assert hard[peer]["runs"] == [] and str(tmp_path / venv) in hard[peer]["skipped"]
        assert "make peers" in hard[peer]["skipped"] and doc["against"][peer]["skipped"]
    assert doc["speed"]["defaults_median_seconds"] == run["seconds"] and doc["speed"]["fastest_peer"] is None
    assert doc["speed"]["passed"] is None  # no peer measured: no verdict
    assert doc["published"]["hard"] and doc["recipe"]["file"] == str(RECIPE_FILE)
    for bad, name in ((["--seeds", "x"], "--seeds"), (["--variants", "rigeo"], "rigeo"),
                      (["--peer-venv", "figaroh"], "NAME=PATH"), (["--against", "", "--peer-venv", "x=/y"], "x")):
        r = CliRunner().invoke(app, ["benchmark", "peers", *bad, "--out", str(tmp_path / "no.json")])
        assert r.exit_code == 2 and name in r.output and not (tmp_path / "no.json").exists()


TRUTH_DRIVER = """
import sys
import numpy as np
from sensorless_studies.benchmarks.peers import peer_case
c = np.load(sys.argv[1])
assert c["q"].shape == c["tau"].shape and c["box_half_extents"].shape == (len(c["body_names"]), 3)
truth = peer_case(str(c["case"]), int(c["seed"]), train_samples=len(c["q"])).truth.robot.inertial_parameters()
np.savez(sys.argv[2], params=truth, info='{"fake": true}')
"""


def _fake_venv(folder: Path, pythonpath: str) -> Path:
    """A venv-like folder whose bin/python is this interpreter with our sources on its path."""
    (folder / "bin").mkdir(parents=True)
    py = folder / "bin" / "python"
    py.write_text(f'#!/bin/sh\nPYTHONPATH="{pythonpath}" exec "{sys.executable}" "$@"\n')
    py.chmod(0o755)
    return folder


def test_peer_harness_scores_a_driver_that_returns_the_truth(tmp_path):
    """The harness, end to end: a fake peer returning the true parameters scores nRMSE ≈ 0 and consistent;
    a failing driver and one returning the wrong number of parameters are errors, not crashes."""
    import sensorless

    src = str(Path(sensorless.__file__).resolve().parents[1])
    drivers = tmp_path / "drivers"
    drivers.mkdir()
    (drivers / "truth_driver.py").write_text(TRUTH_DRIVER)
    (drivers / "broken_driver.py").write_text("raise SystemExit('cannot fit this')\n")
    (drivers / "short_driver.py").write_text("import sys, numpy as np\nnp.savez(sys.argv[2], params=np.ones(7))\n")
    venvs = {p: _fake_venv(tmp_path / p, src) for p in ("truth", "broken", "short")}
    res = run_peers(DEFAULT_RECIPE, seeds=(0,), cases=("hard",), variants=(), against=("truth", "broken", "short"),
                    peer_venvs=venvs, drivers=drivers, train_samples=40, work=tmp_path / "work")
    hard = res["cases"]["hard"]
    truth = hard["truth"]
    assert truth["n_errors"] == 0 and truth["mean_nrmse_percent"] < 1e-8 and truth["all_consistent"]
    assert truth["runs"][0]["info"] == {"fake": True} and truth["min_seconds"] > 0
    assert "cannot fit this" in hard["broken"]["runs"][0]["error"] and "mean_nrmse_percent" not in hard["broken"]
    assert "expected 60 finite parameters" in hard["short"]["runs"][0]["error"]
    assert (tmp_path / "work" / "hard" / "seed0" / "case.npz").is_file()
    assert res["speed"]["fastest_peer"] == "truth" and res["speed"]["passed"] is None


def test_recipe_override_changes_the_case(ur5):
    short = Recipe(rate=200.0)
    assert np.isclose(peer_case("hard", 0, ur5, short).train.t[-1], 599 / 200.0)


def test_case_file_boxes_hold_the_recipe_truths(tmp_path, ur5):
    """The per-body boxes given to the peers (rigeo's realisability shape) contain the link meshes and
    leave room for every recipe truth: each body's second moment about the joint frame, diag(½ tr(I) 1 − I),
    is at most m · max(lo², hi²) per axis (a body outside could not be realised in its box). The URDF's
    UR5 wrists alone need up to 60× what their meshes' box allows."""
    from sensorless_studies.benchmarks.peer_runs import write_case
    from sensorless.identification.ellipsoids import body_points, load_geometry

    pts = body_points(ur5, load_geometry(ur5))
    for seed in DEFAULT_RECIPE.seeds:
        case = peer_case("hard", seed, ur5, train_samples=20)
        case_file, log = write_case(tmp_path / str(seed), case, ur5)
        z = np.load(case_file)
        assert list(z["body_names"]) == list(ur5.body_names) and z["q"].shape == (20, 6) and log.is_file()
        lo, hi = z["box_center"] - z["box_half_extents"], z["box_center"] + z["box_half_extents"]
        P = case.truth.robot.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(ur5.body_names):
            assert np.all(pts[b] >= lo[k] - 1e-12) and np.all(pts[b] <= hi[k] + 1e-12)
            m, p = P[k, 0], P[k]
            inertia = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
            second = np.diag(0.5 * np.trace(inertia) * np.eye(3) - inertia)
            assert np.all(second <= m * np.maximum(lo[k] ** 2, hi[k] ** 2)), (seed, b)

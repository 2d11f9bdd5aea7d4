"""Validation on a log where the robot holds a pose: RMSE and bias in N·m, never an NRMSE of a
torque range that is current noise (real logs printed 14–278 % without comment)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import Trajectory, write_npz
from sensorless.excitation import random_fourier
from sensorless.identification.metrics import static_rows, torque_metrics
from sensorless.testing import perturbed_truth, synthetic_trajectory

LOCK = ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]


def test_static_joints_report_rmse_and_bias_not_nrmse():
    rng = np.random.default_rng(0)
    meas = rng.normal(0, 0.01, (200, 2)) + [5.0, 0.0]
    meas[:, 1] += np.sin(np.linspace(0, 6, 200))
    pred = meas + [0.2, 0.05]
    m = torque_metrics(meas, pred, ["a", "b"], static=np.array([True, False]))
    d = m.to_dict()
    assert d["per_joint"]["a"]["nrmse"] is None and d["per_joint"]["a"]["static"]
    assert abs(d["per_joint"]["a"]["bias"] - 0.2) < 1e-9 and abs(d["per_joint"]["a"]["rmse"] - 0.2) < 1e-9
    assert d["mean_nrmse"] == d["per_joint"]["b"]["nrmse"] and d["static_joints"] == ["a"]
    held = Trajectory(t=np.arange(5.0), q=np.array([[0.1, 0.0]] * 4 + [[0.1, 0.5]]), joint_names=("a", "b"))
    assert static_rows(held, ["a", "b"]).tolist() == [True, False]


def test_cli_validation_on_a_held_pose(panda, tmp_path):
    truth = perturbed_truth(panda, rng=0)
    train = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(100, 10.0), noise_std=0.05, rng=2)
    pose = random_fourier(panda, rng=3).sample(100, 4.0)
    q = np.tile(pose.q[0], (len(pose), 1))
    held = synthetic_trajectory(truth, pose.with_(q=q, v=np.zeros_like(q), a=np.zeros_like(q)), noise_std=0.05, rng=4)
    write_npz(train, tmp_path / "train.npz")
    write_npz(held, tmp_path / "held.npz")
    r = CliRunner().invoke(app, ["identify", "--robot", "panda", *LOCK, "--data", str(tmp_path / "train.npz"),
                                 "--validate", str(tmp_path / "held.npz"), "--method", "ols", "--joint-terms",
                                 "fv,fc,offset", "--no-plot", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    assert "at rest" in r.output and "N·m rms" in r.output
    val = json.loads((tmp_path / "m" / "result.json").read_text())["validation"][str(tmp_path / "held.npz")]
    for model in ("ols", "cad"):
        per = val[model]["per_joint"]
        assert all(d["nrmse"] is None and d["static"] and np.isfinite(d["bias"]) for d in per.values())
        assert val[model]["mean_nrmse"] is None

    # predict reports the held pose as identify --validate does (issue 40: it printed NRMSE of 16–172 %)
    r = CliRunner().invoke(app, ["predict", "--robot", "panda", "--model", str(tmp_path / "m"), "--data",
                                 str(tmp_path / "held.npz"), "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 0, r.output
    assert "at rest" in r.output and "N·m rms" in r.output
    got = json.loads(str(np.load(tmp_path / "p.npz")["metrics"]))
    assert got["mean_nrmse"] is None and set(got["static_joints"]) == set(val["ols"]["per_joint"])
    for j, d in got["per_joint"].items():
        assert d["nrmse"] is None and d["static"]
        assert d["rmse"] == pytest.approx(val["ols"]["per_joint"][j]["rmse"], rel=1e-6)
        assert d["bias"] == pytest.approx(val["ols"]["per_joint"][j]["bias"], rel=1e-6, abs=1e-9)

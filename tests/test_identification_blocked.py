"""Without --validate, identify reports the blocked held-out error of its training logs (issue 42).

The figure must be what a held-out log would say: on a simulated UR5 whose torque noise is known, the
blocked RMSE of a correct model is the noise (a model refit without a block predicts it as well as the
noise allows), at or above the training RMSE.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.blocked import LABEL, blocked_held_out
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory

NOISE = 0.2


@pytest.fixture(scope="module")
def log():
    ur5 = load_robot("ur5")
    truth = perturbed_truth(ur5, rng=0)
    return synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(200.0, 12.0), noise_std=NOISE, rng=2)


def test_the_blocked_error_of_a_correct_model_is_the_noise(log):
    result = identify(load_robot("ur5"), log, method="ols", joint_terms=("fv", "fc", "offset", "armature"))
    m = blocked_held_out(result, [log], {})
    assert m is not None and m.n_samples == len(log)
    np.testing.assert_allclose(m.rmse, NOISE, rtol=0.15)
    assert np.all(m.rmse >= result.train_metrics.rmse * 0.999)


def test_identify_without_validate_prints_and_stores_it_labelled(log, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_npz(log, "log.npz")
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", "log.npz", "--method", "ols", "--no-plot",
                                 "--out", "m"])
    text = " ".join(r.output.split())
    assert r.exit_code == 0, r.output
    assert "blocked held-out, training logs: 5 contiguous time blocks" in text and "nrmse [%]" in text, text
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    b = doc["blocked_held_out"]
    assert b["label"] == LABEL and b["blocks"] == 5 and set(b["per_joint"]) == set(load_robot("ur5").joint_names)
    assert 0.8 * NOISE < b["mean_rmse"] < 1.2 * NOISE
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", "log.npz", "--validate", "log.npz",
                                 "--method", "ols", "--no-plot", "--out", "v"])
    assert r.exit_code == 0 and "blocked held-out" not in r.output  # a held-out log is the figure then
    assert "blocked_held_out" not in json.loads((tmp_path / "v" / "result.json").read_text())

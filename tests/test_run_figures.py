"""sensorless.run.figures: the figure jobs of a run hold every array the drawing needs (a decimated
window of the log, each model's prediction on it), and a run makes them only with ``execution.plot``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.run import RunConfig, identify_run
from sensorless.run.figures import PLOT_POINTS, figure_jobs, plot_window
from sensorless.testing import perturbed_truth, synthetic_trajectory


@pytest.fixture(scope="module")
def path(tmp_path_factory, ur5):
    """A 30 s UR5 log at 100 Hz: more samples than a figure shows."""
    d = tmp_path_factory.mktemp("figures")
    truth = perturbed_truth(ur5, rng=3)
    write_npz(synthetic_trajectory(truth, random_fourier(ur5, rng=51).sample(100, 30.0), noise_std=0.05, rng=52),
              d / "train.npz")
    return d / "train.npz"


@pytest.fixture(scope="module")
def run(path):
    return identify_run(RunConfig.from_options(robot="ur5", data=[path], joint_terms="fv,fc,offset",
                                               coulomb_smoothing=0.02, method="ols", weights="none"))


def test_jobs_hold_the_decimated_window_and_each_prediction(run, tmp_path):
    traj = run.train[0]
    models = {"OLS": run.model, "CAD": run.cad}
    assert figure_jobs(traj, run.structure, models, run.train, run.result.parameters, tmp_path, None, None) == []
    jobs = figure_jobs(traj, run.structure, models, run.train, run.result.parameters, tmp_path, "ur5: torques",
                       "ur5: friction")
    assert [(k, p) for k, _, p in jobs] == [("torques", tmp_path / "torques.png"), ("friction", tmp_path / "friction.png")]
    arrays = jobs[0][1]
    step = math.ceil(len(traj) / PLOT_POINTS)
    assert len(traj) == 3000 and step == 2 and len(arrays["t"]) == 1500
    part = traj.take(np.arange(0, len(traj), step))
    assert np.array_equal(arrays["t"], part.t) and np.array_equal(arrays["measured"], run.structure.target(part))
    assert set(arrays["predictions"]) == {"OLS", "CAD"}
    for k, m in models.items():
        assert np.allclose(arrays["predictions"][k], m.predict(part), rtol=0, atol=1e-12)
    assert arrays["rows"] == list(run.structure.row_names) and "whole log, 1500 points" in arrays["title"]
    assert jobs[1][1]["title"] == "ur5: friction"


def test_a_run_makes_figures_only_with_plot(run, path):
    assert [k for k, _, _ in run.figures] == ["torques", "friction"]
    seen = []
    quiet = identify_run(RunConfig.from_options(robot="ur5", data=[path], joint_terms="fv,fc,offset",
                                                coulomb_smoothing=0.02, method="ols", weights="none", plot=False),
                         figures=seen.append)
    assert quiet.figures == [] and seen == []
    assert np.array_equal(quiet.result.parameters, run.result.parameters)  # figures change no number
    no_friction = identify_run(RunConfig.from_options(robot="ur5", data=[path], joint_terms="offset",
                                                      method="ols", weights="none"), figures=seen.append)
    assert [k for k, _, _ in no_friction.figures] == ["torques"] and seen == [no_friction.figures]


def test_plot_window_draws_the_torques(run, tmp_path):
    pytest.importorskip("matplotlib")
    paths = plot_window(run.train[0], run.structure, {"OLS": run.model}, tmp_path, "ur5")
    assert paths == [tmp_path / "torques.png"] and paths[0].stat().st_size > 1000

"""sensorless.run.backend: the local backend, driven directly, gives the parameters of the whole run
bitwise; a scheduler selects the Dask backend."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.data.trims import LogTrims
from sensorless.excitation import random_fourier
from sensorless.run import RunConfig, identify_run
from sensorless.run.backend import DaskBackend, Job, LocalBackend, backend_for
from sensorless.run.checks import check_run_config
from sensorless.run.model import load_run_robot, model_structure
from sensorless.testing import perturbed_truth, synthetic_trajectory


class Bars:
    """Progress bars that count what the backend reports."""

    def __init__(self):
        self.steps, self.advanced = [], 0

    def step(self, name, total=None):
        self.steps.append((name, total))
        return self

    def advance(self, n=1):
        self.advanced += n

    def update(self, done, total=None, note=None):
        pass

    def callback(self, name):
        return None

    def close(self):
        pass


@pytest.fixture(scope="module")
def data(tmp_path_factory, ur5):
    d = tmp_path_factory.mktemp("backend")
    truth = perturbed_truth(ur5, rng=7)
    paths = []
    for k, seed in enumerate((21, 23)):
        traj = synthetic_trajectory(truth, random_fourier(ur5, rng=seed).sample(100, 2.5), noise_std=0.05, rng=seed + 1)
        paths.append(d / f"train{k}.npz")
        write_npz(traj, paths[-1])
    return paths


def _prep(config):
    lg = config.logs
    return dict(columns=lg.columns, rate=lg.rate, lowpass=lg.lowpass, savgol_window=lg.savgol_window,
                decimate=lg.decimate, gains=lg.gains, trim=LogTrims.parse(None), resample=lg.resample,
                velocity=lg.velocity, max_gap=lg.max_gap, outliers=lg.outliers, rest=lg.rest, time_unit=lg.time_unit,
                base_velocity=lg.base_velocity, pose_max_gap=lg.pose_max_gap, wrench_frames=None)


@pytest.mark.parametrize("options", [dict(coulomb_smoothing="0.02", joint_terms="fv,fc,offset"),
                                     dict(joint_terms="fv,fc,offset")],  # the friction law measured
                         ids=["fixed-law", "auto-law"])
def test_local_backend_gives_the_run_parameters(data, options):
    config = RunConfig.from_options(robot="ur5", data=data, method="wls", weights="none", plot=False, **options)
    eps, vs = check_run_config(config)
    r = load_run_robot("ur5")
    bars = Bars()
    backend = backend_for(Job(config, r, _prep(config), eps, vs, bars))
    assert isinstance(backend, LocalBackend)
    train, used, skipped = backend.read(list(data), bars.advance)
    assert len(train) == 2 and used == list(data) and skipped == [] and bars.advanced == 2
    structure = model_structure(r, config.model.joint_terms, 0.0 if eps == "auto" else eps, None, None, 0.0,
                                "projected")
    fit = backend.fit(structure, train, used, skipped, [], {}, None)
    assert fit.streamed is None and fit.equations is fit.result.equations and fit.train is train
    assert ("regressor (samples)", sum(len(t) for t in train)) in bars.steps

    run = identify_run(config)
    assert np.array_equal(fit.result.parameters, run.result.parameters)
    assert fit.result.settings.get("friction") == run.result.settings.get("friction")
    assert ("friction" in fit.result.settings) == (eps == "auto")


def test_a_scheduler_selects_the_dask_backend(data, tmp_path):
    config = RunConfig.from_options(robot="ur5", data=data, scheduler="tcp://127.0.0.1:1", joint_terms="fv")
    b = backend_for(Job(config, None, {}, 0.0, "auto", Bars()))
    assert isinstance(b, DaskBackend)
    assert b.read(list(data)) == ([], list(data), [])  # the workers read the files
    assert b.contact_logs(list(data), []) is None  # no wrench mode: nothing read on the client

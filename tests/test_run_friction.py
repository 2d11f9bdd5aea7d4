"""sensorless.run.friction: when the friction law is measured, on which logs, and what result.json
records about it."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.data.trims import LogTrims
from sensorless.excitation import random_fourier
from sensorless.regressor import ModelStructure
from sensorless.run import RunConfig, identify_run
from sensorless.run.friction import (client_friction, friction_logs, friction_settings, measure_friction,
                                     needs_friction_law)
from sensorless.run.logs import load_logs
from sensorless.run.model import model_structure
from sensorless.testing import perturbed_truth, synthetic_trajectory

PREP = dict(columns=None, rate=None, lowpass=None, savgol_window=None, decimate=1, trim=LogTrims.parse(None))


@pytest.fixture(scope="module")
def log(tmp_path_factory, ur5):
    d = tmp_path_factory.mktemp("friction")
    truth = perturbed_truth(ur5, rng=9)
    traj = synthetic_trajectory(truth, random_fourier(ur5, rng=31).sample(100, 3.0), noise_std=0.05, rng=32)
    write_npz(traj, d / "train.npz")
    return d / "train.npz"


def test_when_the_law_is_measured(ur5, solo12):
    plain = ModelStructure(ur5, joint_terms=("fv", "fc"), coulomb_smoothing=0.0)
    assert needs_friction_law(plain, "auto") and not needs_friction_law(plain, 0.02)
    assert needs_friction_law(ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck")), 0.02)  # its candidates
    contact = model_structure(solo12, "fv,fc", 0.0, "FL_FOOT,FR_FOOT,HL_FOOT,HR_FOOT", None, 0.0, "projected")
    assert not needs_friction_law(contact, "auto")


def test_the_first_log_unless_it_holds_a_joint_still(ur5, log):
    s = ModelStructure(ur5, joint_terms=("fv", "fc"))
    [moving] = load_logs([log], ur5, **PREP)
    still = moving.with_(q=np.where(np.arange(ur5.model.nq) == 2, moving.q[:1], moving.q))
    assert friction_logs(s, [moving], ["a"]) == ([moving], ["a"])
    assert friction_logs(s, [moving, still], ["a", "b"]) == ([moving], ["a"])
    logs, paths = friction_logs(s, [still, moving], ["b", "a"])
    assert logs == [still, moving] and paths == ["b", "a"]


def test_the_measured_law_is_what_the_run_records(ur5, log):
    s = ModelStructure(ur5, joint_terms=("fv", "fc", "offset"), coulomb_smoothing=0.0)
    [train] = load_logs([log], ur5, **PREP)
    _, law = measure_friction(s, [train], [log], ur5, PREP, "auto", "auto", None)
    eps = law.coulomb_smoothing
    assert set(eps) == set(ur5.joint_names) and all(np.isfinite(e) and e > 0 for e in eps.values())
    doc = friction_settings(law, law, [log])
    assert doc["coulomb_smoothing_mode"] == "auto" and doc["coulomb_smoothing_from"] == [str(log)]
    assert doc["coulomb_smoothing"] == eps
    assert "coulomb_smoothing_from" not in friction_settings(law, None, [log])  # nothing measured: nothing recorded

    run = identify_run(RunConfig.from_options(robot="ur5", data=[log], joint_terms="fv,fc,offset", method="ols",
                                              weights="none", plot=False))
    recorded = run.doc["settings"]["friction"]
    assert recorded["coulomb_smoothing_from"] == [str(log)] and recorded["coulomb_smoothing_mode"] == "auto"
    assert recorded["coulomb_smoothing"] == pytest.approx(eps, rel=1e-12)


def test_a_cluster_run_without_the_first_log_falls_back_to_sgn(ur5):
    s = ModelStructure(ur5, joint_terms=("fv", "fc"))
    with pytest.warns(UserWarning, match=r"`execution\.scheduler`.*sgn\(v\)"):
        got, fit = client_friction(s, [], "remote.npz", ur5, PREP, "auto", "auto", None)
    assert got is s and fit is None

"""A logged v that is not dq/dt is refused or warned about with its figures (issue 42).

With q and v swapped, the model explained nothing (relative RMS 0.94 on shoulder_lift) and every
command exited 0. ``sensorless.data.velocity_check.check_velocity`` compares the logged v with dq/dt per
moving joint; ``prepare`` (every command reading a log) refuses what cannot be a velocity of that joint
(swapped, another unit, another joint) and warns about a delayed or scaled one. The logs carry what a
lab log has (4-decimal rounding, encoder steps, holding torque at rest, joint flexibility, stamp
jitter), which must raise nothing.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import KUKA
from sensorless.cli import app
from sensorless.data import Trajectory, prepare, read_trajectory, write_npz
from sensorless.data.velocity_check import check_velocity
from sensorless.errors import DataError, DataWarning
from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.testing import (RealArtefacts, one_joint_at_a_time, perturbed_truth, synthetic_trajectory,
                                with_real_artefacts)

LAB = RealArtefacts(q_step=2 * np.pi / 2**17, decimals=4, holding=0.5, stiffness=2e4, jitter=2e-5)


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def lab_log(ur5):
    """A UR5 log at 500 Hz with a lab's artefacts."""
    truth = perturbed_truth(ur5, rng=1)
    tr = synthetic_trajectory(truth, random_fourier(ur5, rng=2).sample(500.0, 10.0), noise_std=0.05, rng=3)
    return with_real_artefacts(tr, LAB, rng=4)


def _swap(tr, a, b):
    v = tr.v.copy()
    v[:, [a, b]] = v[:, [b, a]]
    return tr.with_(v=v)


def test_a_lab_log_passes_without_a_word(lab_log):
    check = check_velocity(lab_log.t, lab_log.q, lab_log.v, lab_log.joint_names)
    assert not check.refused and not check.warned, [j.describe() for j in check.joints]
    assert all(j.best_correlation > 0.99 and abs(j.scale - 1) < 0.02 for j in check.joints)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        prepare(lab_log)
    assert not [x for x in w if "dq/dt" in str(x.message)]


def test_one_joint_at_a_time_judges_only_the_moving_joints(ur5):
    t = np.arange(0, 24, 1 / 250)
    q, v, a = one_joint_at_a_time(t, np.zeros(6), amplitude=0.6, period=4.0)
    truth = perturbed_truth(ur5, rng=1)
    motion = Trajectory(t=t, q=q, v=v, a=a, tau=np.zeros_like(q), joint_names=ur5.joint_names)
    tr = synthetic_trajectory(truth, motion, noise_std=0.05, rng=3)
    tr = with_real_artefacts(tr, LAB, rng=5)
    check = check_velocity(tr.t, tr.q, tr.v, tr.joint_names)
    assert not check.refused and not check.warned
    assert len(check.joints) + len(check.still) == 6


@pytest.mark.parametrize("case, needle", [
    ("q and v swapped", "r = -"),
    ("v in degrees", "v = 57.3·dq/dt"),
    ("v of another joint", "'shoulder_lift_joint' r = "),
])
def test_what_cannot_be_the_joints_velocity_is_refused(lab_log, case, needle):
    tr = {"q and v swapped": lab_log.with_(q=lab_log.v, v=lab_log.q),
          "v in degrees": lab_log.with_(v=np.degrees(lab_log.v)),
          "v of another joint": _swap(lab_log, 1, 2)}[case]
    with pytest.raises(DataError) as e:
        prepare(tr)
    text = str(e.value)
    assert needle in text and "velocity='from-q'" in text and "\n" not in text, text
    if case == "v of another joint":
        assert "matches 'elbow_joint'" in text and "matches 'shoulder_lift_joint'" in text, text
    prepare(tr, velocity="from-q")  # the user's way out when q is right


def test_a_delayed_or_scaled_velocity_is_warned_with_the_lag_and_scale(lab_log):
    delay = 10  # samples at 500 Hz: 20 ms
    late = lab_log.with_(v=np.vstack([np.repeat(lab_log.v[:1], delay, axis=0), lab_log.v[:-delay]]))
    with pytest.warns(DataWarning, match=r"at lag 20 ms") as w:
        prepare(late)
    assert len([x for x in w if "dq/dt" in str(x.message)]) == 1  # one warning for the log, every joint in it
    with pytest.warns(DataWarning, match=r"v = 1\.25·dq/dt"):
        prepare(lab_log.with_(v=1.25 * lab_log.v))


def test_identify_and_predict_refuse_swapped_columns(tmp_path, lab_log, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_npz(lab_log, "log.npz")
    write_npz(lab_log.with_(q=lab_log.v, v=lab_log.q), "swapped.npz")
    run = CliRunner().invoke
    r = run(app, ["identify", "--robot", "ur5", "--data", "swapped.npz", "--method", "ols", "--no-plot", "--out", "m"])
    text = " ".join(r.output.split())
    assert r.exit_code == 2 and "the logged v is not the derivative of the logged q" in text, text
    assert "--velocity from-q" in text and "--columns" in text and not (tmp_path / "m").exists(), text
    assert run(app, ["identify", "--robot", "ur5", "--data", "log.npz", "--method", "ols", "--no-plot",
                     "--out", "m"]).exit_code == 0
    r = run(app, ["predict", "--robot", "ur5", "--model", "m", "--data", "swapped.npz", "--out", "p.npz"])
    assert r.exit_code == 2 and "not the derivative" in " ".join(r.output.split()), r.output


def test_the_real_kuka_logs_pass():
    if not KUKA.exists():
        pytest.skip(f"real data not available: {KUKA}")
    robot = load_robot(str(KUKA / "model" / "kuka_lwr4.urdf"))
    for k in (1, 2, 3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tr = read_trajectory(KUKA / "data" / "KUKA" / "HW" / f"measurements_{k}.npz", robot=robot)
        check = check_velocity(tr.t, tr.q, tr.v, tr.joint_names)
        assert not check.refused and not check.warned, [j.describe() for j in check.joints]

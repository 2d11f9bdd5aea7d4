"""Mocap base pose cleaning: held samples, NaN gaps, yaw wrap and quaternion sign flips,
against a Pinocchio-integrated ground truth."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from sensorless.data import Trajectory
from sensorless.data.base_pose import clean_base_pose, with_base_pose
from sensorless.errors import DataError, TimestampError

FREQS = np.array([0.3, 0.7, 1.1])


def _twist(t):
    """Smooth LOCAL twist and its derivative; yaw rate ~2 rad/s so the yaw wraps."""
    A = np.array([[0.4, -0.3, 0.2, 0.3, -0.2, 0.6], [0.2, 0.3, -0.1, 0.2, 0.3, 0.4], [0.1, 0.1, 0.2, -0.2, 0.1, 0.3]])
    ph = np.arange(6) * 0.7
    w = 2 * np.pi * FREQS[:, None, None]
    arg = w * t[None, :, None] + ph
    v = np.sum(A[:, None, :] * np.sin(arg), axis=0) + np.array([0, 0, 0, 0, 0, 2.0])
    a = np.sum(A[:, None, :] * w * np.cos(arg), axis=0)
    return v, a


@pytest.fixture(scope="module")
def truth():
    model = pin.Model()
    model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
    rate, sub = 100.0, 50
    t = np.arange(500) / rate
    tf = np.arange(len(t) * sub) / (rate * sub)
    vf, _ = _twist(tf + 0.5 / (rate * sub))
    q = pin.neutral(model)
    Q = np.empty((len(t), 7))
    for i in range(len(tf)):
        if i % sub == 0:
            Q[i // sub] = q
        q = pin.integrate(model, q, vf[i] / (rate * sub))
    v, a = _twist(t)
    return t, Q, v, a


def test_recovers_twist_and_acceleration_through_holds_gaps_and_wrap(truth):
    t, Q, v, a = truth
    rng = np.random.default_rng(0)
    pos = Q[:, :3].copy()
    rpy = Rotation.from_quat(Q[:, 3:]).as_euler("xyz")
    assert np.abs(np.diff(rpy[:, 2])).max() > np.pi  # the yaw wraps in this log
    for start in np.sort(rng.choice(np.arange(20, 480), 15, replace=False)):  # the tracker holds its last output
        pos[start : start + 3] = pos[start - 1]
        rpy[start : start + 3] = rpy[start - 1]
    pos[200:205] = np.nan  # dropout
    pose = clean_base_pose(t, pos, rpy, orientation_format="rpy", t_out=t[50:450], cutoff_hz=8.0)
    assert pose.report["n_held"] >= 15 and pose.report["n_nonfinite"] == 5
    np.testing.assert_allclose(pose.base_q[:, :3], Q[50:450, :3], atol=2e-3)
    dots = np.abs(np.sum(pose.base_q[:, 3:] * Q[50:450, 3:], axis=1))
    assert dots.min() > 1 - 1e-5  # same rotation (up to sign)
    err_v = np.abs(pose.base_v - v[50:450]).max()
    err_a = np.abs(pose.base_a - a[50:450]).max()
    assert err_v < 0.03 * np.abs(v).max(), err_v
    assert err_a < 0.15 * np.abs(a).max(), err_a
    # the same stream as quaternions with random sign flips gives the same result
    quat = Rotation.from_euler("xyz", rpy).as_quat() * rng.choice([-1.0, 1.0], size=(len(t), 1))
    pose_q = clean_base_pose(t, pos, quat, t_out=t[50:450], cutoff_hz=8.0)
    np.testing.assert_allclose(pose_q.base_v, pose.base_v, atol=1e-9)
    # naive finite differences of the held stream are far off (the check can fail)
    naive = np.gradient(np.where(np.isnan(pos), 0, pos), t, axis=0)[50:450]
    world_v = np.einsum("nij,nj->ni", Rotation.from_quat(Q[50:450, 3:]).as_matrix(), v[50:450, :3])
    assert np.abs(naive - world_v).max() > 10 * err_v


def test_with_base_pose_fills_a_joint_log_and_errors_name_the_problem(truth):
    t, Q, _, _ = truth
    log = Trajectory(t=t[10:400], q=np.zeros((390, 1)), joint_names=("j",))
    out = with_base_pose(log, t, Q[:, :3], Q[:, 3:])
    assert out.base_q.shape == (390, 7) and out.base_a.shape == (390, 6)
    assert "mocap" in out.units["processing"]
    held = Q.copy()
    held[100:160] = held[99]  # the tracker held its last pose for 0.6 s
    with pytest.raises(DataError, match="0.610 s gap"):
        clean_base_pose(t, held[:, :3], held[:, 3:])
    with pytest.raises(TimestampError, match="backwards"):
        clean_base_pose(t[::-1], Q[:, :3], Q[:, 3:])
    with pytest.raises(DataError, match="unit quaternion"):
        clean_base_pose(t, Q[:, :3], 2 * Q[:, 3:])
    with pytest.raises(DataError, match="outside"):
        with_base_pose(log.with_(t=log.t + 10), t, Q[:, :3], Q[:, 3:])


# ---- issue 27: base velocity from a logged pose through the CLI path ---------------------------------
FEET = ("left_sole_link", "right_sole_link")


@pytest.fixture(scope="module")
def legs():
    from sensorless.robot import load_robot

    return load_robot("talos_legs")


@pytest.fixture(scope="module")
def mocap_walk(legs):
    """A humanoid walking log whose base pose comes from a 100 Hz tracker: the truth at 1 kHz (wrench_log),
    sampled with periods of 9, 10 or 11 ms (±10 % jitter), 3 dropped frames, tracker noise 0.3 mm /
    1 mrad, and the last 5 samples repeating the pose before them (the tracker lost the markers)."""
    from sensorless.testing import perturbed_truth
    from sensorless_studies.simulation.wrench_log import walking_flags, wrench_log

    truth = perturbed_truth(legs, rng=3)
    hi = wrench_log(truth.robot, FEET, duration=6.0, rate=1000.0, flags=walking_flags(6000, 2, 800), seed=2)
    rng = np.random.default_rng(0)
    idx = np.concatenate([[0], np.cumsum(rng.integers(9, 12, size=700))])
    idx = idx[idx < len(hi)]
    idx = np.delete(idx, np.sort(rng.choice(np.arange(50, len(idx) - 50), 3, replace=False)))
    log = hi.take(idx)
    bq = log.base_q.copy()
    bq[:, :3] += 3e-4 * rng.standard_normal((len(bq), 3))
    bq[:, 3:] = (Rotation.from_rotvec(1e-3 * rng.standard_normal((len(bq), 3))) * Rotation.from_quat(bq[:, 3:])).as_quat()
    bq[-5:] = bq[-6]
    log = log.with_(base_q=bq, base_v=None, base_a=None, extras={"contact_forces": log.extras["contact_forces"]})
    return log, hi, truth


def _truth_at(hi, field, t):
    return np.column_stack([np.interp(t, hi.t, getattr(hi, field)[:, k]) for k in range(6)])


def test_load_log_derives_the_base_twist_from_a_jittery_held_pose(legs, mocap_walk, tmp_path):
    """The CLI's preprocessing (load_log, --base-velocity auto): the trailing repeats are clipped with a
    warning counting them, the jitter and dropped frames pass the default gap limit, the twist is
    within 5 mm/s and 15 mrad/s RMS of the truth (tracker noise 0.3 mm / 1 mrad, 0.2 s derivative window)."""
    from sensorless.data import write_npz
    from sensorless.data.prepare import load_log
    from sensorless.errors import DataWarning

    log, hi, _ = mocap_walk
    path = write_npz(log, tmp_path / "walk.npz")
    with pytest.warns(DataWarning, match=r"the last 5 pose sample\(s\) repeat .* clipped 5 sample\(s\) after"):
        out = load_log(path, legs, None, None, None, None, 1)
    assert log.t[-6] - 0.011 < out.t[-1] <= log.t[-6] and out.provenance["base_pose_clipped"]["trailing"] == 5
    assert out.provenance["base_v"].startswith("derived from the logged base pose")
    inner = slice(20, -20)  # the derivative window's edges
    err = out.base_v[inner] - _truth_at(hi, "base_v", out.t)[inner]
    rms_lin, rms_ang = np.sqrt(np.mean(err[:, :3] ** 2)), np.sqrt(np.mean(err[:, 3:] ** 2))
    assert rms_lin < 5e-3 and rms_ang < 15e-3, (rms_lin, rms_ang)
    acc = out.base_a[inner] - _truth_at(hi, "base_a", out.t)[inner]
    assert np.sqrt(np.mean(acc**2)) < 0.3 * np.sqrt(np.mean(hi.base_a**2))
    # the quaternion's sign may flip sample to sample in a tracker's output: same twist
    flipped = log.base_q.copy()
    flipped[1::2, 3:] *= -1
    with pytest.warns(DataWarning):
        alt = load_log(write_npz(log.with_(base_q=flipped), tmp_path / "flip.npz"), legs, None, None, None, None, 1)
    np.testing.assert_allclose(alt.base_v, out.base_v, atol=1e-9)
    # --base-velocity logged on a log without base_v: nothing derived (the identification then says so)
    with pytest.warns(DataWarning):
        assert load_log(path, legs, None, None, None, None, 1, base_velocity="logged").base_v is None


def test_cli_identify_from_a_mocap_pose(legs, mocap_walk, tmp_path):
    """End to end: identify with measured wrenches on the mocap log (no base_v in it) prints the clipped
    samples, records where base_v came from, and finds the total mass within 1 %."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.data import write_npz

    log, _, truth = mocap_walk
    path = write_npz(log, tmp_path / "walk.npz")
    out = tmp_path / "id"
    res = CliRunner().invoke(app, ["identify", "--robot", "talos_legs", "--data", str(path), "--out", str(out),
                                   "--contact-frames", ",".join(FEET), "--contact-dims", "6,6", "--contact-mode", "wrench",
                                   "--joint-terms", "", "--method", "ols", "--no-plot", "--urdf-values", "regularised",
                                   "--accept-implausible", "--accept-implausible-torques", "--lowpass", "15"])
    assert res.exit_code == 0, res.output
    assert "clipped 5 sample(s) after" in " ".join(res.output.split())
    doc = json.loads((out / "result.json").read_text())
    pre = doc["settings"]["preprocessing"]
    assert pre["base_velocity"] == "auto" and pre["lowpass"] == 15
    signals = doc["settings"]["signals"][str(path)]
    assert signals["base_v"].startswith("derived from the logged base pose") and "low-pass 15 Hz" in signals["base_v"]
    assert {"base_q", "base_v", "base_a", "contact_forces"} <= set(signals["lowpass"]["channels"])
    m_true = float(truth.robot.inertial_parameters().reshape(-1, 10)[:, 0].sum())
    assert doc["mass_properties"]["total_mass"] == pytest.approx(m_true, rel=0.01)


def test_pose_ends_rest_and_gap_rules(truth):
    """Leading and trailing repeats are clipped (with the count), a base at rest is kept however long,
    and the default gap limit is 10 median periods of the pose samples."""
    from sensorless.errors import DataWarning

    t, Q, v, _ = truth
    held = Q.copy()
    held[:7] = held[7]  # the tracker's first pose reported for the 7 samples before it
    held[-4:] = held[-5]
    with pytest.warns(DataWarning, match=r"first 7 .* clipped 7 sample\(s\) before .* last 4 .* clipped 4"):
        pose = clean_base_pose(t, held[:, :3], held[:, 3:], t_out=t)
    np.testing.assert_array_equal(pose.t, t[7:-4])
    assert pose.report["leading"] == 7 and pose.report["trailing"] == 4
    # a base at rest for 1.5 s (poses exactly equal, then a slow start) is not a gap
    tt = np.arange(600) / 100.0
    x = np.where(tt < 1.5, 0.0, 0.05 * (tt - 1.5) ** 3)
    rest = np.column_stack([x, np.zeros((600, 2))])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (600, 1))
    p = clean_base_pose(tt, rest, quat, cutoff_hz=None)
    assert p.report["n_at_rest"] >= 149 and p.report["n_held"] == 0
    np.testing.assert_allclose(p.base_v[:, 0], np.where(tt < 1.5, 0, 0.15 * (tt - 1.5) ** 2), atol=2e-3)
    # a 0.12 s hold while moving is 12 periods at 100 Hz: refused, naming the option
    moving = Q.copy()
    moving[200:211] = moving[199]
    with pytest.raises(DataError, match=r"0.120 s gap .* 10 median pose periods .*`pose_max_gap=PERIODS`"):
        clean_base_pose(t, moving[:, :3], moving[:, 3:])
    ok = clean_base_pose(t, moving[:, :3], moving[:, 3:], max_gap_periods=15)
    assert ok.report["max_gap"] == pytest.approx(0.12) and ok.report["n_held"] == 11


def test_a_pose_that_never_changes_is_a_base_at_rest():
    t = np.arange(200) / 100.0
    pose = clean_base_pose(t, np.tile([0.1, 0.2, 0.9], (200, 1)), np.tile([0, 0, 0.6, 0.8], (200, 1)))
    assert pose.report["n_at_rest"] == 200 and np.abs(pose.base_v).max() < 1e-9 and np.abs(pose.base_a).max() < 1e-9


def test_base_pose_as_position_and_euler_angles_in_two_arrays(tmp_path):
    """Issue 40: a base pose logged as position and roll/pitch/yaw in two arrays is mapped with
    --columns 'base_q=base_position,base_rpy' and --base-rpy (stored sample-major or channel-major)."""
    import scipy.io
    from scipy.spatial.transform import Rotation

    from sensorless.data import read_trajectory
    from sensorless.data.limits import read_options

    n = 300
    t = np.arange(n) / 100.0
    pos = np.column_stack([0.1 * t, np.sin(t), 0.3 + 0.01 * np.cos(3 * t)])
    rpy = np.column_stack([0.1 * np.sin(t), 0.05 * np.cos(2 * t), 2.5 * t - 3.0])  # yaw through ±π
    q = np.column_stack([np.sin(t), np.cos(t)])
    np.savez(tmp_path / "log.npz", t=t, q=q, base_position=pos, base_rpy=rpy)
    scipy.io.savemat(tmp_path / "log.mat", {"t": t, "q": q, "base_position": pos.T, "base_rpy": rpy.T})
    want = np.hstack([pos, Rotation.from_euler("xyz", rpy).as_quat()])
    cols = {"base_q": "base_position,base_rpy"}
    for name in ("log.npz", "log.mat"):
        with pytest.raises(DataError, match=r"base_q.*6.*"):  # six columns are not a quaternion pose
            read_trajectory(tmp_path / name, columns=cols)
        with read_options(base_rpy=True):
            tr = read_trajectory(tmp_path / name, columns=cols)
        np.testing.assert_allclose(tr.base_q, want, atol=1e-12)
    with read_options(base_rpy=True), pytest.raises(DataError, match=r"no base pose.*base_position,base_rpy"):
        read_trajectory(tmp_path / "log.npz")

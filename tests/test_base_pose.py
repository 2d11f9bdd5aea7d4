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

"""Data of the legged-robot and position-controlled docs (`sensorless example ...`) and the
accelerometer a simulated log carries (`simulation.wrench_log.accelerometer_reading`)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import imu_frame_base_acceleration, read_trajectory
from sensorless.robot import load_robot
from sensorless_studies.simulation.wrench_log import accelerometer_reading, wrench_log

FEET = ("left_sole_link", "right_sole_link")


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos", floating_base=True)


def test_accelerometer_on_the_torso_gives_back_the_base_acceleration(talos):
    """Oracle: the reading at TALOS's torso IMU (lever arm, torso joints in between), inverted by
    the identification's own formula, is the log's base acceleration; at rest it reads +g up."""
    log = wrench_log(talos, FEET, duration=2.0, stand=0.5, seed=3)
    imu = accelerometer_reading(talos, log, "imu_link")
    back = imu_frame_base_acceleration(talos, log.with_(extras={**log.extras, "imu_acc": imu}), "imu_link",
                                       angular_acc=log.base_a[:, 3:])
    assert np.abs(back - log.base_a).max() < 1e-8 * (1 + np.abs(log.base_a).max())
    assert np.abs(log.base_a[:20]).max() < 1e-12  # standing still: the specific force is gravity, up
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, talos.full_configuration(log.q[:1], log.base_q[:1])[0])
    up = data.oMf[talos.model.getFrameId("imu_link")].rotation.T @ np.array([0.0, 0.0, 9.81])
    assert np.allclose(imu[0], up, atol=1e-9)


def test_talos_walk_example_is_the_documented_log(tmp_path):
    """`sensorless example talos-walk`: sole wrenches (N, 2, 6) with contact flags, a torso
    accelerometer, no joint torques and no base acceleration (the IMU gives it)."""
    r = CliRunner().invoke(app, ["example", "talos-walk", "--out", str(tmp_path / "talos")])
    assert r.exit_code == 0, r.output
    traj = read_trajectory(tmp_path / "talos" / "walk.npz")
    n = len(traj)
    assert n == 600 and traj.tau is None and traj.base_a is None and traj.base_q.shape == (n, 7)
    assert traj.extras["contact_forces"].shape == (n, 2, 6) and traj.extras["imu_acc"].shape == (n, 3)
    flags = np.asarray(traj.extras["contact"], bool)
    assert flags.all(axis=1).any() and (~flags).any()  # double and single support


def test_examples_are_listed():
    r = CliRunner().invoke(app, ["example", "--list"])
    assert r.exit_code == 0
    for name in ("solo12-walk", "talos-walk", "rail-leg", "talos-leg-drive"):
        assert name in r.output

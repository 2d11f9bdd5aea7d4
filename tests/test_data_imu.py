"""Base acceleration from an IMU accelerometer: oracles against Pinocchio and the simulator,
the NPZ/CLI path, errors, and why it matters (differentiating the base twist at 100 Hz)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import base_acceleration, imu_base_acceleration, read_trajectory, write_npz
from sensorless.errors import DataError
from sensorless.testing import NoiseSpec
from sensorless_studies.simulation.quadruped import make_truth, simulate


def test_specific_force_oracle_with_offset_against_pinocchio(solo12, rng):
    """An accelerometer at r on the base reads Rᵀ(p̈_r − g); Pinocchio's classical
    acceleration of a frame at r gives p̈_r, and the formula must return the base's
    LOCAL spatial acceleration a[:6] exactly."""
    model = solo12.model.copy()
    r = np.array([0.05, -0.02, 0.03])
    fid = model.addFrame(pin.Frame("imu", 1, 0, pin.SE3(np.eye(3), r), pin.FrameType.OP_FRAME))
    data = model.createData()
    rows = []
    for _ in range(5):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        v, a = rng.normal(size=model.nv), rng.normal(size=model.nv)
        pin.forwardKinematics(model, data, q, v, a)
        pin.updateFramePlacements(model, data)
        acc_r = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL).linear  # Rᵀ p̈_r
        R = data.oMi[1].rotation
        f = acc_r - R.T @ model.gravity.linear
        rows.append((q[:7], v[:6], f, a[3:6], a[:6]))
    base_q, base_v, f, alpha, expected = (np.array(x) for x in zip(*rows))
    got = imu_base_acceleration(base_q, base_v, f, alpha, offset=r, g=-model.gravity.linear[2])
    np.testing.assert_allclose(got, expected, atol=1e-10)
    # ignoring the offset is wrong (the check can fail)
    assert np.abs(imu_base_acceleration(base_q, base_v, f, alpha) - expected).max() > 1e-3


@pytest.fixture(scope="module")
def wobble(solo12):
    return simulate("wobble", solo12, duration=4.0, seed=3, truth=make_truth(solo12, 0), coulomb_velocity=0.03)


def test_simulated_accelerometer_gives_the_true_base_acceleration(solo12):
    traj, gt = simulate("trot", solo12, duration=2.0, seed=1, truth=make_truth(solo12, 0), noise=NoiseSpec.none())
    got = imu_base_acceleration(traj.base_q, traj.base_v, traj.extras["imu_acc"], gt.base_a[:, 3:])
    np.testing.assert_allclose(got, gt.base_a, atol=1e-9)
    assert abs(np.median(traj.extras["imu_acc"][:, 2]) - 9.81) < 1.0  # reads +g up when standing


def test_imu_beats_differentiating_the_base_twist(wobble):
    traj, gt = wobble
    err = {}
    for use_imu in (True, False):
        ba = base_acceleration(traj, window=9, use_imu=use_imu).base_a
        err[use_imu] = np.sqrt(np.mean((ba[:, :3] - gt.base_a[:, :3]) ** 2))
    print(f"\nbase linear acceleration RMSE: IMU {err[True]:.3f} m/s², SG of base_v {err[False]:.3f} m/s²")
    assert err[True] < 0.05 and err[True] < 0.3 * err[False]


def test_npz_and_cli_path_fill_base_acceleration_from_the_imu(solo12, wobble, tmp_path):
    from sensorless.run.logs import load_logs

    traj, gt = wobble
    path = write_npz(traj, tmp_path / "w.npz")  # no base_a in the file, imu_acc is
    back = read_trajectory(path, robot=solo12)
    assert back.base_a is None and back.extras["imu_acc"].shape == (len(back), 3)
    (log,) = load_logs([path], solo12, None, None, None, None, 1)
    assert "imu_acc" in log.units["processing"]
    assert np.sqrt(np.mean((log.base_a[:, :3] - gt.base_a[:, :3]) ** 2)) < 0.05


def test_bad_imu_data_is_a_clear_error(solo12, wobble, tmp_path):
    traj, _ = wobble
    bad = traj.with_(extras={**traj.extras, "imu_acc": traj.extras["imu_acc"][:, :2]})
    with pytest.raises(DataError, match="imu_acc.*expected"):
        read_trajectory(write_npz(bad, tmp_path / "b.npz"), robot=solo12)
    nan = traj.extras["imu_acc"].copy()
    nan[7, 1] = np.nan
    with pytest.raises(DataError, match="imu_acc.*sample 7"):
        base_acceleration(traj.with_(extras={**traj.extras, "imu_acc": nan}))
    with pytest.raises(DataError, match="base_q and base_v"):
        base_acceleration(traj.with_(base_v=None))


def _with_imu_frame(robot, parent_joint: int, placement):
    """A copy of ``robot`` with an 'imu' frame on joint ``parent_joint``."""
    from sensorless.robot import Robot

    model = robot.model.copy()
    model.addFrame(pin.Frame("imu", parent_joint, 0, placement, pin.FrameType.OP_FRAME))
    return Robot(model, name=robot.name, source=robot.source)


@pytest.mark.parametrize("parent", [1, 4])  # on the base, and on a leg link (joints in between)
def test_imu_frame_rotation_and_lever_arm_oracle(solo12, rng, parent):
    """An accelerometer in a model frame (rotated, offset, possibly on another body) reads
    R_sᵀ(p̈_s − g); imu_frame_base_acceleration must return the true LOCAL base acceleration."""
    from sensorless.data import Trajectory
    from sensorless.data.imu import imu_frame_base_acceleration

    placement = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.5, 1.2), np.array([0.05, -0.02, 0.03]))
    robot = _with_imu_frame(solo12, parent, placement)
    model, data = robot.model, robot.data
    fid = model.getFrameId("imu")
    Q, V, A, F = [], [], [], []
    for _ in range(6):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        v, a = rng.normal(size=model.nv), rng.normal(size=model.nv)
        pin.forwardKinematics(model, data, q, v, a)
        Rs = pin.updateFramePlacement(model, data, fid).rotation
        acc = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear
        F.append(Rs.T @ (acc - model.gravity.linear))
        Q.append(q), V.append(v), A.append(a)
    Q, V, A, F = map(np.array, (Q, V, A, F))
    idx = [robot.v_index(j) for j in robot.joint_names]
    traj = Trajectory(t=np.arange(6) * 0.01, q=Q[:, 7:], v=V[:, idx], a=A[:, idx], base_q=Q[:, :7],
                      base_v=V[:, :6], joint_names=robot.joint_names, extras={"imu_acc": F})
    got = imu_frame_base_acceleration(robot, traj, "imu", A[:, 3:6], g=-model.gravity.linear[2])
    np.testing.assert_allclose(got, A[:, :6], atol=1e-9)
    if parent == 1:  # same as the closed form with R_bs and the lever arm
        closed = imu_base_acceleration(Q[:, :7], V[:, :6], F, A[:, 3:6], offset=placement.translation,
                                       g=-model.gravity.linear[2], rotation=placement.rotation)
        np.testing.assert_allclose(closed, A[:, :6], atol=1e-9)
    # assuming base axes (the old behaviour) is wrong: the check can fail
    naive = imu_base_acceleration(Q[:, :7], V[:, :6], F, A[:, 3:6], g=-model.gravity.linear[2])
    assert np.abs(naive - A[:, :6]).max() > 0.1


def test_imu_frame_errors(solo12, panda):
    from sensorless.data import Trajectory
    from sensorless.data.imu import imu_frame_base_acceleration
    from sensorless.errors import RobotModelError

    n = len(solo12.joint_names)
    traj = Trajectory(t=[0.0, 0.01], q=np.zeros((2, n)), v=np.zeros((2, n)), base_q=np.tile([0, 0, 0, 0, 0, 0, 1.0], (2, 1)),
                      base_v=np.zeros((2, 6)), joint_names=solo12.joint_names)
    with pytest.raises(RobotModelError, match="no frame 'imu_nope'"):
        imu_frame_base_acceleration(solo12, traj.with_(extras={"imu_acc": np.zeros((2, 3))}), "imu_nope", np.zeros((2, 3)))
    with pytest.raises(DataError, match="no 'imu_acc'"):
        imu_frame_base_acceleration(solo12, traj, "base_link", np.zeros((2, 3)))
    with pytest.raises(RobotModelError, match="`floating_base=True`"):
        imu_frame_base_acceleration(panda, traj, "panda_link0", np.zeros((2, 3)))

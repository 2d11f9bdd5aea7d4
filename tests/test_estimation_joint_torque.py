"""Joint-torque estimation from F/T + IMU + encoders against Pinocchio RNEA in the world frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import RobotModelError, ShapeMismatchError
from sensorless.estimation.joint_torque import FTSensor, ImuSpec, JointTorqueEstimator
from sensorless.robot import Robot, load_robot

G = np.array([0.0, 0.0, -9.81])
# distal part of the ankle body (foot sole plate), in the sensor frame
PLATE = pin.Inertia(0.6, np.array([0.01, 0.0, -0.012]), np.diag([8e-4, 2.2e-3, 2.9e-3]))


def _with_frames(robot: Robot) -> Robot:
    """Add an IMU frame on the base and a (rotated) F/T frame on each ankle."""
    m = robot.model.copy()
    root = 1 if robot.floating_base else 0
    imu = pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0.1, np.pi / 2), np.array([0.05, -0.02, 0.08]))
    m.addFrame(pin.Frame("imu", root, 0, imu, pin.FrameType.OP_FRAME))
    for side in ("right", "left"):
        name = f"leg_{side}_6_joint"
        if not m.existJointName(name):
            continue
        j = m.getJointId(name)
        ft = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.3), np.array([0.0, 0.0, -0.087]))
        m.addFrame(pin.Frame(f"{side}_ft", j, 0, ft, pin.FrameType.OP_FRAME))
        m.addFrame(pin.Frame(f"{side}_contact", j, 0, pin.SE3(np.eye(3), np.array([0.06, 0.02, -0.107])), pin.FrameType.OP_FRAME))
    m.armature[:] = 0.0  # link-side torques (the estimator's default)
    return Robot(m, name=robot.name, source=robot.source)


def _world_truth(robot: Robot, rng, n: int, contact_frames: dict[str, str], balance: str | None = None):
    """Random states in the world with gravity, contact wrenches, and the exact sensor readings.

    ``balance``: choose that side's contact wrench so that the floating-base rows vanish
    (the base is unactuated), as physics requires when that wrench is to be recovered."""
    m = robot.model
    d = m.createData()
    fb = robot.floating_base
    out = {k: [] for k in ("q", "dq", "ddq", "tau", "gyro", "acc", "dgyro")}
    out["ft"] = {s: [] for s in contact_frames}
    out["contact"] = {s: [] for s in contact_frames}
    lo, hi = robot.position_limits()
    for _ in range(n):
        qj = rng.uniform(lo, hi)
        qb = None
        if fb:
            quat = pin.Quaternion(rng.normal(size=4)).normalized()
            qb = np.r_[rng.normal(size=3), quat.coeffs()]
        q = robot.full_configuration(qj[None], None if qb is None else qb[None])[0]
        v, a = rng.normal(size=m.nv), rng.normal(size=m.nv)
        pin.forwardKinematics(m, d, q, v, a)
        pin.updateFramePlacements(m, d)
        wrenches = {side: np.r_[rng.normal(0, 80, 3), rng.normal(0, 8, 3)] for side in contact_frames}
        if balance is not None:
            wrenches[balance] = np.zeros(6)
            tau0 = pin.rnea(m, d, q, v, a, _fext(m, contact_frames, wrenches))
            J = pin.computeFrameJacobian(m, d, q, m.getFrameId(contact_frames[balance]), pin.LOCAL)
            wrenches[balance] = np.linalg.solve(J[:, :6].T, tau0[:6])
            pin.forwardKinematics(m, d, q, v, a)
            pin.updateFramePlacements(m, d)
        fext = _fext(m, contact_frames, wrenches)
        for side, cf in contact_frames.items():
            w = wrenches[side]
            out["contact"][side].append(w)
            fid = m.getFrameId(cf)
            # sensor reading: contact wrench at the sensor minus the sole plate's inertial + gravity wrench
            sid = m.getFrameId(f"{side}_ft")
            oMs = d.oMf[sid]
            sMc = oMs.inverse() * d.oMf[fid]
            vs = pin.getFrameVelocity(m, d, sid, pin.LOCAL)
            a_s = pin.getFrameAcceleration(m, d, sid, pin.LOCAL)
            g_s = pin.Motion(oMs.rotation.T @ G, np.zeros(3))
            h = PLATE * (a_s - g_s) + vs.cross(PLATE * vs)
            out["ft"][side].append((sMc.act(pin.Force(w)) - h).vector)
        tau = pin.rnea(m, d, q, v, a, fext)  # world frame, model gravity
        iid = m.getFrameId("imu")
        oMi = d.oMf[iid]
        out["gyro"].append(pin.getFrameVelocity(m, d, iid, pin.LOCAL).angular)
        out["acc"].append(pin.getFrameClassicalAcceleration(m, d, iid, pin.LOCAL).linear - oMi.rotation.T @ G)
        out["dgyro"].append(pin.getFrameAcceleration(m, d, iid, pin.LOCAL).angular)
        idx = [robot.v_index(j) for j in robot.joint_names]
        out["q"].append(qj)
        out["dq"].append(v[idx])
        out["ddq"].append(a[idx])
        out["tau"].append(tau[idx])
    res = {k: np.array(v) for k, v in out.items() if k not in ("ft", "contact")}
    res["ft"] = {k: np.array(v) for k, v in out["ft"].items()}
    res["contact"] = {k: np.array(v) for k, v in out["contact"].items()}
    return res


def _fext(m, contact_frames, wrenches):
    fext = pin.StdVec_Force()
    for _ in range(m.njoints):
        fext.append(pin.Force.Zero())
    for side, cf in contact_frames.items():
        fid = m.getFrameId(cf)
        fext[m.frames[fid].parentJoint] += m.frames[fid].placement.act(pin.Force(wrenches[side]))
    return fext


@pytest.fixture(scope="module")
def leg_fixed():
    from sensorless_studies.simulation.leg_model import talos_right_leg

    return _with_frames(talos_right_leg(foot_plate=False))


@pytest.fixture(scope="module")
def legs_floating():
    return _with_frames(load_robot("talos_legs"))


def _estimator(robot, sides, **kw):
    sensors = [FTSensor(side, f"{side}_ft", PLATE) for side in sides]
    return JointTorqueEstimator(robot, sensors, ImuSpec("imu"), **kw)


def test_fixed_base_leg_exact(leg_fixed):
    rng = np.random.default_rng(0)
    tr = _world_truth(leg_fixed, rng, 40, {"right": "right_contact"})
    est = _estimator(leg_fixed, ["right"]).estimate(tr["q"], tr["dq"], tr["ddq"], {"right": tr["ft"]["right"]},
                                                     gyro=tr["gyro"], acc=tr["acc"])
    assert np.abs(est.tau).max() > 10  # non-trivial torques
    np.testing.assert_allclose(est.tau, tr["tau"], atol=1e-9, rtol=0)


def test_floating_base_exact_without_base_pose(legs_floating):
    rng = np.random.default_rng(1)
    tr = _world_truth(legs_floating, rng, 40, {"right": "right_contact", "left": "left_contact"})
    est = _estimator(legs_floating, ["right", "left"]).estimate(
        tr["q"], tr["dq"], tr["ddq"], tr["ft"], gyro=tr["gyro"], acc=tr["acc"], dgyro=tr["dgyro"])
    np.testing.assert_allclose(est.tau, tr["tau"], atol=1e-9, rtol=0)
    # the IMU's angular acceleration matters once the base rotates: dropping it breaks exactness
    bad = _estimator(legs_floating, ["right", "left"]).estimate(
        tr["q"], tr["dq"], tr["ddq"], tr["ft"], gyro=tr["gyro"], acc=tr["acc"])
    assert np.abs(bad.tau - tr["tau"]).max() > 1e-3


def test_unknown_wrench_recovered_by_least_squares(legs_floating):
    rng = np.random.default_rng(2)
    tr = _world_truth(legs_floating, rng, 30, {"right": "right_contact", "left": "left_contact"}, balance="left")
    assert np.abs(tr["contact"]["left"]).max() > 10
    est = _estimator(legs_floating, ["right"], unknown_wrench_frame="left_contact").estimate(
        tr["q"], tr["dq"], tr["ddq"], {"right": tr["ft"]["right"]}, gyro=tr["gyro"], acc=tr["acc"], dgyro=tr["dgyro"])
    np.testing.assert_allclose(est.unknown_wrench, tr["contact"]["left"], atol=1e-8, rtol=0)
    np.testing.assert_allclose(est.tau, tr["tau"], atol=1e-8, rtol=0)
    assert np.abs(est.unactuated_residual).max() < 1e-8


def test_errors(leg_fixed, legs_floating):
    est = _estimator(leg_fixed, ["right"])
    with pytest.raises(ShapeMismatchError):
        est.estimate(np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 5)), np.zeros((3, 6)), acc=np.zeros((3, 3)))
    with pytest.raises(ShapeMismatchError):
        est.estimate(np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 6)), {"left": np.zeros((3, 6))}, acc=np.zeros((3, 3)))
    with pytest.raises(RobotModelError):
        JointTorqueEstimator(leg_fixed, [FTSensor("x", "no_such_frame")])
    with pytest.raises(RobotModelError):
        JointTorqueEstimator(legs_floating, [FTSensor("right", "right_ft")])  # floating base without IMU
    with pytest.raises(RobotModelError):
        _estimator(leg_fixed, ["right"], unknown_wrench_frame="right_contact")  # fixed base: no unactuated rows

"""Passive joints (no actuator): no torque channel, a known zero generalized force, friction terms only.

Oracles: an acrobot (passive shoulder, actuated elbow) simulated by Pinocchio's forward dynamics
satisfies the structure's equations with its true parameters on both rows, and identification
recovers what it identifies; the passive row adds identifiable parameters. A known foot force on
the rail-mounted leg is recovered from the rows of known generalized force.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data.trajectory import Trajectory
from sensorless.data.validation import validate_trajectory
from sensorless.errors import DataError, JointNameError, ParameterError, RobotModelError, ShapeMismatchError
from sensorless.identification import base_parameters, identify
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot

ACROBOT = """<?xml version="1.0"?>
<robot name="acrobot">
  <link name="world"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.15"/><mass value="1.2"/>
    <inertia ixx="0.012" ixy="0" ixz="0" iyy="0.011" iyz="0" izz="0.002"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0.01 0 -0.12"/><mass value="0.7"/>
    <inertia ixx="0.006" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.001"/></inertial></link>
  <joint name="shoulder" type="continuous"><parent link="world"/><child link="upper"/><axis xyz="0 1 0"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 -0.3"/><axis xyz="0 1 0"/></joint>
</robot>
"""
SHOULDER_FV = 0.05  # viscous friction of the passive shoulder [N·m·s/rad]


@pytest.fixture(scope="module")
def acrobot_urdf(tmp_path_factory):
    p = tmp_path_factory.mktemp("acrobot") / "acrobot.urdf"
    p.write_text(ACROBOT)
    return p


def _acrobot_log(robot, seconds=6.0, dt=1e-3) -> Trajectory:
    """Forward dynamics with the shoulder unactuated (its only force: viscous friction) and the
    elbow driven along a multi-sine; q, v, v̇ exact, τ logged for both joints (the shoulder's is 0)."""
    model, data = robot.model, robot.data
    n = int(seconds / dt)
    q, v = np.array([0.4, -0.3]), np.zeros(2)
    Q, V, A, T = (np.zeros((n, 2)) for _ in range(4))
    ish, iel = robot.v_index("shoulder"), robot.v_index("elbow")
    for i in range(n):
        t = i * dt
        tau = np.zeros(2)
        ref = 0.8 * np.sin(2.1 * t) + 0.4 * np.sin(5.3 * t + 1.0) + 0.2 * np.sin(9.7 * t)
        tau[iel] = 8.0 * (ref - q[iel]) - 0.3 * v[iel]  # the elbow tracks a multi-sine
        tau[ish] = -SHOULDER_FV * v[ish]
        a = pin.aba(model, data, robot.full_configuration(q[None])[0], v, tau)
        Q[i], V[i], A[i] = q, v, a
        T[i, 1] = tau[iel]
        v = v + dt * a
        q = q + dt * v
    names = robot.joint_names  # shoulder, elbow
    order = [robot.v_index(j) for j in names]
    return Trajectory(t=np.arange(n) * dt, q=Q[:, order], v=V[:, order], a=A[:, order], tau=T,
                      joint_names=names)


def test_a_passive_joint_has_no_torque_row_to_fit_and_no_motor_terms(acrobot_urdf):
    r = load_robot(acrobot_urdf, passive_joints=["shoulder"])
    assert r.actuated_joints == ("elbow",) and r.passive_joints == ("shoulder",)
    assert r.term_joints == ("elbow", "shoulder") and r.selection.shape == (1, 2)
    s = ModelStructure(r, joint_terms=("fv", "fc", "stribeck", "offset", "armature"))
    assert s.terms_of("shoulder") == ("fv", "fc", "stribeck") and "armature" in s.terms_of("elbow")
    assert s.row_names == ["elbow", "shoulder"]  # its row is kept: the generalized force 0 is known
    log = _acrobot_log(r, seconds=0.5)
    # whatever the log holds in the shoulder's torque column, its target is 0
    y = s.target(log.with_(tau=log.tau + np.array([[7.0, 0.0]])))
    assert np.all(y[:, 1] == 0.0) and np.allclose(y[:, 0], log.tau[:, 1])
    with pytest.raises(RobotModelError, match="passive joint 'shoulder' cannot have the term"):
        ModelStructure(r, joint_terms="shoulder=fv,offset;elbow=fv")
    with pytest.raises(RobotModelError, match="locked and passive"):
        load_robot(acrobot_urdf, passive_joints=["shoulder"], lock_joints=["shoulder"])
    with pytest.raises(JointNameError, match="unknown passive"):
        load_robot(acrobot_urdf, passive_joints=["hip"])


def test_passive_rows_hold_with_the_true_parameters_and_add_information(acrobot_urdf):
    r = load_robot(acrobot_urdf, passive_joints=["shoulder"])
    log = _acrobot_log(r)
    s = ModelStructure(r, joint_terms=("fv",))
    truth = s.prior()
    truth[s.joint_term_index("shoulder", "fv")] = SHOULDER_FV
    # oracle: both rows of W π − y vanish (the integrator's own error aside)
    err = s.torques(truth, log) - s.target(log)
    assert np.max(np.abs(err)) < 1e-9 * max(1.0, np.max(np.abs(log.tau)))
    res = identify(s, log, method="ols", weights=None)
    b = res.base
    np.testing.assert_allclose(b.base(res.parameters), b.base(truth), rtol=1e-6, atol=1e-9)
    assert res.parameters[s.joint_term_index("shoulder", "fv")] == pytest.approx(SHOULDER_FV, rel=1e-6)
    # the same robot with the shoulder merely "not actuated" (rows of the elbow only) identifies less
    elbow_only = ModelStructure(load_robot(acrobot_urdf, actuated_joints=["elbow"]), joint_terms=("fv",))
    assert elbow_only.row_names == ["elbow"]
    assert base_parameters(elbow_only).rank < b.rank


def test_a_log_without_the_passive_torque_column(acrobot_urdf):
    r = load_robot(acrobot_urdf, passive_joints=["shoulder"])
    log = _acrobot_log(r, seconds=0.2)
    short = log.with_(tau=log.tau[:, 1:])  # torque of the elbow only
    out = validate_trajectory(short, r)
    assert out.tau.shape == (len(log), 2) and np.all(out.tau[:, 0] == 0.0)
    nan = log.with_(tau=np.column_stack([np.full(len(log), np.nan), log.tau[:, 1]]))
    assert np.all(validate_trajectory(nan, r).tau[:, 0] == 0.0)  # no channel: anything there is ignored
    with pytest.raises(ShapeMismatchError, match="`passive_joints=JOINT`"):
        validate_trajectory(short, load_robot(acrobot_urdf))


def test_settings_robot_round_trip_and_mismatch(tmp_path, acrobot_urdf):
    from sensorless.identification.artifact import (load_model_folder, load_model_robot, read_robot_settings,
                                                    save_model_folder)

    r = load_robot(acrobot_urdf, passive_joints=["shoulder"])
    s = ModelStructure(r, joint_terms=("fv", "fc", "armature"))
    res = identify(s, _acrobot_log(r, seconds=3.0), method="ols", weights=None)
    assert res.parameters[s.joint_term_index("shoulder", "armature")] == 0.0  # a zero column: fixed at 0
    save_model_folder(tmp_path, res)
    doc = json.loads((tmp_path / "result.json").read_text())
    assert doc["settings"]["robot"] == {"floating_base": False, "lock": [], "passive": ["shoulder"], "frames": []}
    assert read_robot_settings(tmp_path)["passive"] == ["shoulder"]
    again = load_model_robot(acrobot_urdf, tmp_path)
    art = load_model_folder(tmp_path, again)
    np.testing.assert_array_equal(art.parameters, res.parameters)
    with pytest.raises(ParameterError, match="passive joint"):
        load_model_folder(tmp_path, load_robot(acrobot_urdf))


def test_force_from_the_rows_of_known_generalized_force(tmp_path):
    """Rail-mounted leg, true model, consistent state (forward dynamics with the rail unactuated):
    the foot force is recovered exactly, and the rail row alone carries the vertical force."""
    from sensorless.estimation.force import CartesianForceEstimator
    from sensorless.torque_models import PhysicalModel
    from sensorless_studies.simulation.hopping_leg import FOOT, TRUTH, leg_robot, leg_urdf

    r = leg_robot(leg_urdf(TRUTH, tmp_path / "leg.urdf"))
    rng = np.random.default_rng(0)
    n = 40
    q = np.column_stack([rng.uniform(0.3, 0.5, n), rng.uniform(-0.8, -0.2, n), rng.uniform(0.5, 1.5, n)])
    v = rng.normal(0, 0.5, (n, 3))
    f_robot = np.column_stack([rng.normal(0, 5, n), np.zeros(n), rng.uniform(10, 80, n)])  # plate on the foot
    fid = r.frame_id(FOOT)
    A, T = np.zeros((n, 3)), np.zeros((n, 3))
    for i in range(n):
        Q = r.full_configuration(q[i:i + 1])[0]
        J = pin.computeFrameJacobian(r.model, r.data, Q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        tau = np.zeros(3)
        tau[r.actuated_v_indices] = rng.normal(0, 3, 2)
        A[i] = pin.aba(r.model, r.data, Q, v[i], tau + J.T @ f_robot[i])
        T[i] = tau[[r.v_index(j) for j in r.joint_names]]
    log = Trajectory(t=np.arange(n) * 1e-3, q=q, v=v, a=A, tau=T, joint_names=r.joint_names)
    s = ModelStructure(r, joint_terms=())
    model = PhysicalModel.from_parameters(s, s.prior())
    est = CartesianForceEstimator(r, FOOT, components="fx,fz")
    assert est.row_names == ["hip", "knee", "rail"]
    F = est.estimate(log, model).F
    np.testing.assert_allclose(F, -f_robot[:, [0, 2]], atol=1e-6)  # the force on the plate
    rail_only = CartesianForceEstimator(r, FOOT, components="fz", joints=["rail"]).estimate(log, model).F[:, 0]
    np.testing.assert_allclose(rail_only, -f_robot[:, 2], atol=1e-6)
    with pytest.raises(RobotModelError, match="unknown components"):
        CartesianForceEstimator(r, FOOT, components="fz,fq")

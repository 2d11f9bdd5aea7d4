"""Legged contact forces from joint torques: against MuJoCo's contact forces (Solo12 trot)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.errors import DataError, RobotModelError
from sensorless.estimation.contact_forces import estimate_contact_forces
from sensorless.estimation.momentum import MomentumDynamics
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot

pytest.importorskip("mujoco")


@pytest.fixture(scope="module")
def trot():
    from sensorless.testing import NoiseSpec
    from sensorless_studies.simulation.quadruped import make_truth, simulate
    from sensorless_studies.simulation.quadruped_log import JOINT_TERMS
    from sensorless_studies.simulation.quadruped_profiles import PROFILES, quadruped_robot

    nom = quadruped_robot("solo12")
    truth = make_truth(nom, 0)
    traj, gt = simulate("trot", nom, duration=2.0, seed=1, truth=truth, noise=NoiseSpec.none(), log_rate=100.0,
                        coulomb_velocity=0.03, speed=0.2)
    assert not gt.fell
    st = ModelStructure(truth.robot, joint_terms=JOINT_TERMS, coulomb_smoothing=0.03)
    dyn = MomentumDynamics(st, gt.parameters)
    weight = sum(truth.robot.model.inertias[j].mass for j in range(1, truth.robot.model.njoints)) * 9.81
    return traj, gt, dyn, weight, PROFILES["solo12"].feet


@pytest.mark.parametrize("flags", [None, "detect"])
def test_momentum_contact_forces_match_mujoco(trot, flags):
    """Acceptance: per-foot vertical RMSE ≤ 10 % of the body weight (100 Hz, no accelerations)."""
    traj, gt, dyn, weight, feet = trot
    est = estimate_contact_forces(dyn, traj, feet, flags=flags, contact_offset=gt.foot_radius)
    err = (est.forces - gt.contact_forces)[30:]  # after the observer's start-up
    rmse = np.sqrt(np.mean(err**2, axis=0))  # (feet, xyz)
    assert np.all(rmse[:, 2] <= 0.10 * weight), rmse[:, 2] / weight
    assert np.all(rmse[:, :2] <= 0.05 * weight)
    if flags == "detect":
        assert (est.contact == gt.contact).mean() > 0.9


def test_inverse_dynamics_contact_forces_are_exact_with_true_accelerations(trot):
    traj, gt, dyn, weight, feet = trot
    est = estimate_contact_forces(dyn, traj.with_(a=gt.a, base_a=gt.base_a), feet, method="inverse_dynamics",
                                  contact_offset=gt.foot_radius)
    assert np.sqrt(np.mean((est.forces - gt.contact_forces) ** 2)) < 0.01 * weight
    # without the foot radius the moment arm of the tangential forces is missing: visibly worse
    est0 = estimate_contact_forces(dyn, traj.with_(a=gt.a, base_a=gt.base_a), feet, method="inverse_dynamics")
    assert np.sqrt(np.mean((est0.forces - gt.contact_forces) ** 2)) > np.sqrt(np.mean((est.forces - gt.contact_forces) ** 2))


def test_contact_force_input_errors(trot):
    traj, gt, dyn, _, feet = trot
    with pytest.raises(DataError, match="accelerations"):
        estimate_contact_forces(dyn, traj, feet, method="inverse_dynamics")
    with pytest.raises(DataError, match="contact flags"):
        estimate_contact_forces(dyn, traj.with_(extras={}), feet)
    with pytest.raises(DataError, match="shape"):
        estimate_contact_forces(dyn, traj, feet, flags=np.ones((3, 4), bool))
    with pytest.raises(RobotModelError, match="method"):
        estimate_contact_forces(dyn, traj, feet, method="magic")
    ur5 = ModelStructure(load_robot("ur5"))
    with pytest.raises(RobotModelError, match="floating-base"):
        estimate_contact_forces(MomentumDynamics(ur5, ur5.prior()), traj, feet)


def test_a_massless_root_link_gives_finite_forces_not_nan(trot):
    """The trunk's mass moved onto the first hip body: the robot's dynamics are unchanged except for
    the trunk's own CoM, so the forces stay finite and near the truth (the NaN came from c = h/m)."""
    traj, gt, dyn, weight, feet = trot
    p = dyn.params.copy()
    hip = 10 * 1  # the first body after the trunk
    p[hip:hip + 10] += p[:10]
    p[:10] = 0.0
    est = estimate_contact_forces(MomentumDynamics(dyn.structure, p), traj.with_(a=gt.a, base_a=gt.base_a), feet,
                                  method="inverse_dynamics", contact_offset=gt.foot_radius)
    assert np.all(np.isfinite(est.forces))
    total = est.forces[:, :, 2].sum(axis=1)
    assert abs(np.median(total) / weight - 1) < 0.2  # the feet still carry the robot's weight

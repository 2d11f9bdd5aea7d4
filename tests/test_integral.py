"""Acceleration-free (filtered momentum) regressor: oracles against Pinocchio and the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.estimation.momentum import MomentumDynamics
from sensorless.regressor import ModelStructure
from sensorless.regressor.integral import filtered_rows, filtered_target, momentum_regressors, projection_rate_error
from sensorless.robot import load_robot
from sensorless.simulation.arm_push import simulate_pushes
from sensorless.simulation.synthetic import perturbed_truth


@pytest.fixture(scope="module")
def arm():
    nom = load_robot("ur5")
    truth = perturbed_truth(nom, rng=1)
    st = ModelStructure(truth.robot, coulomb_smoothing=0.05)
    traj, _ = simulate_pushes(truth, nom, [], duration=4.0, log_rate=100.0)
    return st, truth.parameters(), traj


def test_momentum_regressors_match_pinocchio_momentum_and_coriolis(arm):
    """Y_p θ = M v (crba) and Y_b θ = g − Cᵀv + τ_f (computeCoriolisMatrix) on all rows."""
    st, th, traj = arm
    dyn = MomentumDynamics(st, th)
    Q = st.robot.full_configuration(traj.q[:40])
    Yp, Yb = momentum_regressors(st, Q, traj.v[:40])
    P, B = dyn.momentum_series(Q, traj.v[:40])
    np.testing.assert_allclose(Yp @ th, P, atol=1e-10)
    np.testing.assert_allclose(Yb @ th, -B, atol=1e-6)


def test_filtered_regressor_explains_noise_free_torques(arm):
    st, th, traj = arm
    fr = filtered_rows(st, traj, cutoff=4.0)
    rel = np.sqrt(np.mean((fr.W @ th - fr.y) ** 2)) / np.sqrt(np.mean(fr.y**2))
    assert rel < 5e-3
    np.testing.assert_allclose(filtered_target(st, traj), fr.y)
    wrong = th.copy()
    wrong[20:30] *= 1.5  # the elbow link 50 % heavier
    assert np.sqrt(np.mean((fr.W @ wrong - fr.y) ** 2)) > 10 * np.sqrt(np.mean((fr.W @ th - fr.y) ** 2))


def test_projected_filtered_regressor_and_pdot_term():
    """Solo12 wobble (all feet down, noise-free, 100 Hz): exact with Ṗ p, and the error of dropping it
    is measured (it is the documented approximation)."""
    pytest.importorskip("mujoco")
    from sensorless.regressor.contact import ContactStructure
    from sensorless.simulation.quadruped import JOINT_TERMS, NoiseSpec, make_truth, simulate
    from sensorless.simulation.quadruped_profiles import PROFILES, quadruped_robot

    nom = quadruped_robot("solo12")
    truth = make_truth(nom, 0)
    traj, gt = simulate("wobble", nom, duration=2.0, seed=1, truth=truth, noise=NoiseSpec.none(), log_rate=100.0,
                        coulomb_velocity=0.03)
    cs = ContactStructure(nom, contact_frames=PROFILES["solo12"].feet, joint_terms=JOINT_TERMS,
                          contact_offset=gt.foot_radius, coulomb_smoothing=0.03)
    fr = filtered_rows(cs, traj, cutoff=4.0)
    rel = np.sqrt(np.mean((fr.W @ gt.parameters - fr.y) ** 2)) / np.sqrt(np.mean(fr.y**2))
    assert rel < 5e-3
    err = projection_rate_error(cs, traj, gt.parameters)
    assert err["relative"] > 2 * rel  # dropping Ṗ p is visibly worse than the exact form

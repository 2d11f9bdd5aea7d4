"""Payload identification: regressor oracle (Pinocchio inertia merging + RNEA), recovery of a
known mass/CoM on simulated logs, physical consistency, modes and errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import savgol_derivatives
from sensorless.errors import DataError, RobotModelError
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.payload import (
    identify_payload,
    payload_regressor,
    point_mass_parameters,
)
from sensorless.parameters import pseudo_inertia
from sensorless.regressor import ModelStructure
from sensorless.robot import Robot
from sensorless.simulation import TruthModel, perturbed_truth, synthetic_trajectory

FRAME = "panda_hand"
PAYLOAD = pin.Inertia(1.5, np.array([0.01, -0.02, 0.08]), np.diag([0.004, 0.005, 0.003]))


def _with_payload(truth: TruthModel, frame: str, inertia: pin.Inertia) -> TruthModel:
    """The true robot carrying ``inertia`` (in ``frame``), merged by Pinocchio itself."""
    model = truth.robot.model.copy()
    f = model.frames[truth.robot.frame_id(frame)]
    model.inertias[f.parentJoint] = model.inertias[f.parentJoint] + f.placement.act(inertia)
    r = Robot(model, name="with_payload", actuated_joints=truth.robot.actuated_joints)
    return TruthModel(r, truth.fv, truth.fc, truth.offset, truth.armature)


@pytest.fixture(scope="module")
def panda_case(panda):
    truth = perturbed_truth(panda, rng=0)
    free = synthetic_trajectory(truth, random_fourier(panda, rng=1, base_freq=0.1).sample(200, 30.0), noise_std=0.2, rng=2)
    result = identify(ModelStructure(panda), free)
    return truth, result


def test_payload_regressor_matches_rnea_with_the_merged_payload(panda, panda_case):
    truth, _ = panda_case
    loaded = _with_payload(truth, FRAME, PAYLOAD)
    mot = random_fourier(panda, rng=3).sample(50, 2.0)
    Q, V, A = panda.full_configuration(mot.q), panda.full_velocity(mot.v), panda.full_velocity(mot.a)
    delta = loaded.torques(Q, V, A) - truth.torques(Q, V, A)
    Y = payload_regressor(truth.robot, Q, V, A, FRAME)
    assert Y.shape == (len(mot), 7, 10)
    np.testing.assert_allclose(Y @ PAYLOAD.toDynamicParameters(), delta, atol=1e-10)
    np.testing.assert_allclose(point_mass_parameters(2.0, np.array([0.1, 0.2, -0.3])),
                               pin.Inertia(2.0, np.array([0.1, 0.2, -0.3]), np.zeros((3, 3))).toDynamicParameters(), atol=1e-14)


def test_known_payload_recovered_on_the_panda(panda, panda_case):
    truth, result = panda_case
    log = synthetic_trajectory(_with_payload(truth, FRAME, PAYLOAD), random_fourier(panda, rng=5, base_freq=0.1).sample(200, 30.0),
                               noise_std=0.2, rng=6)
    est = identify_payload(result, log, FRAME, n_boot=50)
    assert est.mode == "full" and est.consistent
    assert abs(est.mass - 1.5) / 1.5 < 0.05
    assert np.linalg.norm(est.com - PAYLOAD.lever) < 0.005
    assert 0 < est.mass_std < 0.05 and 0 < est.mass_std_analytic < 0.05
    assert np.all(np.isfinite(est.com_std))
    assert np.all(est.residual_rms_after < est.residual_rms_before)
    doc = est.to_dict()
    assert doc["mass"] == est.mass and len(doc["parameters"]) == 10
    # other modes on the same log
    com = identify_payload(result, log, FRAME, mode="com", n_boot=0)
    assert abs(com.mass - 1.5) / 1.5 < 0.05 and np.linalg.norm(com.com - PAYLOAD.lever) < 0.005
    mass = identify_payload(result, log, FRAME, mode="mass", com=PAYLOAD.lever, n_boot=0)
    assert abs(mass.mass - 1.5) / 1.5 < 0.05 and mass.mass_std_bootstrap is None


def test_consistency_enforced_for_a_point_mass_payload(panda, panda_case):
    """A point mass lies on the boundary (pseudo-inertia of rank 1): with noise, plain least
    squares leaves the physical set; the constrained estimate does not."""
    truth, result = panda_case
    point = pin.Inertia(0.8, np.array([0.0, 0.03, 0.05]), np.zeros((3, 3)))
    log = synthetic_trajectory(_with_payload(truth, FRAME, point), random_fourier(panda, rng=8, base_freq=0.1).sample(200, 20.0),
                               noise_std=0.3, rng=9)
    free = identify_payload(result, log, FRAME, mode="full", consistent=False, n_boot=0)
    assert free.min_pseudo_inertia_eig < 0 and not free.consistent  # the test is not vacuous
    cons = identify_payload(result, log, FRAME, mode="full", consistent=True, n_boot=0)
    assert cons.consistent and np.linalg.eigvalsh(pseudo_inertia(cons.parameters))[0] > -1e-8
    assert abs(cons.mass - 0.8) / 0.8 < 0.05
    # the constrained fit explains the data slightly worse, never better
    assert np.sum(cons.residual_rms_after**2) >= np.sum(free.residual_rms_after**2) - 1e-12


def test_payload_on_the_simulated_surgical_arm():
    """Known mass at the tool tip of the PSM-like arm: identify the arm in free space, then the payload."""
    from sensorless.simulation.surgical_arm import TIP_FRAME
    from sensorless.simulation.trocar import make_datasets, payload_log

    short = dict(free_space=40.0, split=1.0, trocar_multisine=1.0, trocar_probe=1.0, trocar_test=1.0, contact=1.0)
    ds = make_datasets(3, quick=True, durations=short)
    structure = ModelStructure(ds.robot, coulomb_smoothing=ds.truth.coulomb_eps)
    result = identify(structure, savgol_derivatives(ds.free_space))
    m = 0.15
    log = savgol_derivatives(payload_log(ds, pin.Inertia(m, np.array([0.0, 0.005, 0.015]), np.diag([1e-4, 1e-4, 5e-5])),
                                         duration=20.0, seed=3))
    est = identify_payload(result, log, TIP_FRAME, n_boot=30)
    assert abs(est.mass - m) / m < 0.05, est
    assert est.consistent and est.mass_std > 0


def test_bad_inputs(panda, panda_case):
    _, result = panda_case
    log = synthetic_trajectory(perturbed_truth(panda, rng=0), random_fourier(panda, rng=5).sample(100, 1.0))
    with pytest.raises(DataError, match="unknown payload mode"):
        identify_payload(result, log, FRAME, mode="everything")
    with pytest.raises(RobotModelError, match="unknown frame"):
        identify_payload(result, log, "nope")
    with pytest.raises(DataError, match="IdentificationResult"):
        identify_payload(object(), log, FRAME)

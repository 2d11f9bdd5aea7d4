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
from sensorless.identification.payload import identify_payload
from sensorless.identification.payload_model import payload_regressor, point_mass_parameters
from sensorless.parameters import pseudo_inertia
from sensorless.regressor import ModelStructure
from sensorless.robot import Robot
from sensorless.testing import TruthModel, perturbed_truth, synthetic_trajectory

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
    calls = []
    est = identify_payload(result, log, FRAME, n_boot=50, progress=lambda *a: calls.append(a))
    assert est.mode == "full" and est.consistent
    assert calls[-50:] == [(k, 50) for k in range(1, 51)]  # one call per bootstrap resample
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
    from sensorless_studies.simulation.surgical_arm import TIP_FRAME
    from sensorless_studies.simulation.trocar import make_datasets, payload_log

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


# ---- issue 11: payload on the dVRK PSM (coupled joints), paired no-load log, offsets, per-joint check ----
from sensorless_studies.simulation.psm_logs import psm_motion, psm_truth  # noqa: E402

PSM_LINK = "pitch_end"  # the instrument (moved by q1, q2, q3)


def _psm_payload_torques(s, mot, frame: str, inertia: pin.Inertia) -> np.ndarray:
    """Oracle: RNEA of the tree carrying only the payload (merged into the frame's body by
    Pinocchio), mapped to the coordinates by Gᵀ (RNEA is linear in the inertias)."""
    model = s.tree.model.copy()
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia.Zero()
    f = model.frames[s.tree.frame_id(frame)]
    model.inertias[f.parentJoint] = f.placement.act(inertia)
    data = model.createData()
    Q, V, A = s.pinocchio_state(mot.q, mot.v, mot.a)
    return np.array([s.G.T @ pin.rnea(model, data, Q[i], V[i], A[i]) for i in range(len(mot))])


@pytest.fixture(scope="module")
def psm_case():
    rng = np.random.default_rng(7)
    s, p = psm_truth(rng)
    free = psm_motion(1, 15.0)
    free = free.with_(tau=s.evaluate(free.q, free.v, free.a) @ p + rng.normal(size=(len(free), 7)) * 0.01)
    return s, p, identify(s, free)


def test_psm_payload_regressor_matches_the_merged_tree(psm_case):
    """Regression: payload_regressor / identify_payload raised AttributeError ('CoordinateRobot'
    has no 'frame_id') on the PSM. Y_p φ = Gᵀ RNEA(tree with the payload)."""
    s, _, _ = psm_case
    mot = psm_motion(4, 1.0)
    pay = pin.Inertia(0.3, np.array([0.01, -0.02, 0.3]), np.diag([1e-3, 2e-3, 5e-4]))
    for frame in (PSM_LINK, "tool_tip", "rcm"):
        Y = payload_regressor(s.robot, mot.q, mot.v, mot.a, frame)
        assert Y.shape == (len(mot), 7, 10)
        np.testing.assert_allclose(Y @ pay.toDynamicParameters(), _psm_payload_torques(s, mot, frame, pay), atol=1e-10)


@pytest.mark.parametrize("frame,com", [(PSM_LINK, (0.0, 0.0, 0.35)), ("tool_tip", (0.0, 0.0, 0.0))])
def test_payload_on_the_simulated_psm_within_2_percent(psm_case, frame, com):
    s, p, result = psm_case
    m = 0.2
    pay = pin.Inertia(m, np.array(com), np.zeros((3, 3)))
    mot = psm_motion(5, 20.0)
    log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + _psm_payload_torques(s, mot, frame, pay)
                    + np.random.default_rng(8).normal(size=(len(mot), 7)) * 0.01)
    est = identify_payload(result, log, frame, mode="com", n_boot=20)
    assert abs(est.mass - m) / m < 0.02, est
    assert abs(est.weight - m * 9.81) / (m * 9.81) < 0.02
    assert 0 < est.mass_std < 0.02 * m and est.consistent


def test_paired_no_load_log_cancels_model_error_and_session_offset(psm_case):
    """A wrong model (pitch_end 30 % heavier, CoM moved) and a τ2 session offset bias the plain
    estimate; the paired no-load log (same trajectory) with offsets removes both."""
    s, p, _ = psm_case
    from sensorless_studies.experiments.psm_identification import SESSION_OFFSET, paired_payload_logs

    wrong = p.copy()
    k = list(s.robot.body_names).index("pitch_end")
    wrong[10 * k : 10 * k + 4] *= [1.3, 1.6, 1.6, 1.6]
    m = 0.1
    nl, ld = paired_payload_logs(s, p, psm_motion(6, 30.0), pin.Inertia(m, np.array([0.0, 0.0, 0.35]), np.zeros((3, 3))),
                                 PSM_LINK, noise_std=np.full(7, 0.01), corr_seconds=0.05, seed=2)
    model = (s, wrong)
    plain = identify_payload(model, ld, PSM_LINK, mode="com", n_boot=0)
    paired = identify_payload(model, ld, PSM_LINK, no_load=nl, offsets="auto", mode="com", n_boot=0)
    assert abs(plain.mass - m) / m > 0.2  # the test is not vacuous
    assert abs(paired.mass - m) / m < 0.05, paired
    # the auto offsets: fitted where they are distinguishable from the payload (not on the insertion)
    assert "q3" not in paired.settings["offsets"] and "q2" in paired.settings["offsets"]
    assert paired.diagnostics["offset_variance_inflation"]["q3"] > 2.0
    assert paired.offsets[1] == pytest.approx(SESSION_OFFSET[1], abs=0.02)


def test_a_joint_contradicting_the_others_is_flagged(psm_case):
    s, p, result = psm_case
    m = 0.3
    pay = pin.Inertia(m, np.array([0.0, 0.0, 0.0]), np.zeros((3, 3)))
    mot = psm_motion(9, 20.0)
    tau_p = _psm_payload_torques(s, mot, "tool_tip", pay)
    base = s.evaluate(mot.q, mot.v, mot.a) @ p + np.random.default_rng(10).normal(size=(len(mot), 7)) * 0.005
    good = identify_payload(result, mot.with_(tau=base + tau_p), "tool_tip", mode="com", n_boot=0)
    assert good.flagged_joints == [] and all(np.isfinite(c.z) for c in good.per_joint)
    bad_tau = base + tau_p
    bad_tau[:, 1] += 0.6 * tau_p[:, 1]  # q2 sees 60 % more payload torque (a wrong drive gain)
    bad = identify_payload(result, mot.with_(tau=bad_tau), "tool_tip", mode="com", n_boot=0)
    assert bad.flagged_joints == ["q2"], [c.to_dict() for c in bad.per_joint]
    q2 = bad.per_joint[1]
    assert q2.mass > q2.others_mass and abs(q2.others_mass - m) / m < 0.1


def test_hac_uncertainty_accounts_for_correlated_noise(psm_case):
    """With noise correlated over 0.5 s the white-noise standard error is far too small; the
    HAC (block sandwich) and bootstrap errors are not, and cover the actual error."""
    s, p, result = psm_case
    from sensorless_studies.experiments.psm_identification import ar1_noise

    m = 0.2
    pay = pin.Inertia(m, np.array([0.0, 0.0, 0.35]), np.zeros((3, 3)))
    z = []
    for seed in range(4):
        mot = psm_motion(11, 30.0)
        noise = ar1_noise(len(mot), np.full(7, 0.03), 0.5, mot.dt, np.random.default_rng(seed))
        log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + _psm_payload_torques(s, mot, PSM_LINK, pay) + noise)
        est = identify_payload(result, log, PSM_LINK, mode="com", n_boot=100, block_seconds=2.0, seed=seed)
        assert est.mass_std_hac > 2.5 * est.mass_std_analytic
        assert est.mass_std_bootstrap > 2.5 * est.mass_std_analytic
        z.append((est.mass - m) / est.mass_std)
    assert max(abs(x) for x in z) < 3.5, z


def test_paired_log_errors(psm_case):
    s, p, result = psm_case
    mot = psm_motion(12, 3.0)
    log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p)
    with pytest.raises(DataError, match="row by row"):
        identify_payload(result, log, PSM_LINK, no_load=log.take(slice(0, 200)), n_boot=0)
    other = psm_motion(13, 3.0)
    with pytest.raises(DataError, match="not the same trajectory") as exc:
        identify_payload(result, log, PSM_LINK, no_load=other.with_(tau=log.tau), n_boot=0)
    assert "sample" in str(exc.value) and "joint 'q" in str(exc.value)
    with pytest.raises(DataError, match="pair them"):
        identify_payload(result, log, PSM_LINK, no_load=[log, log], n_boot=0)
    with pytest.raises(DataError, match="unknown joint"):
        identify_payload(result, log, PSM_LINK, offsets=["q9"], n_boot=0)


def test_no_payload_in_com_mode_terminates_at_zero(psm_case):
    """With no payload the point-mass CoM c = (m c)/m is noise over noise: the fit (and every
    bootstrap resample) must stop at m = 0 instead of iterating to an overflow."""
    s, p, result = psm_case
    mot = psm_motion(14, 10.0)
    log = mot.with_(tau=s.evaluate(mot.q, mot.v, mot.a) @ p + np.random.default_rng(15).normal(size=(len(mot), 7)) * 0.01)
    est = identify_payload(result, log, PSM_LINK, mode="com", n_boot=50)
    assert est.mass < 5 * est.mass_std + 1e-3 and np.isfinite(est.mass_std)
    assert np.isfinite(est.diagnostics["mass_unconstrained"])

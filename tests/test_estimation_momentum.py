"""Momentum observer: Pinocchio oracles and recovery of a known external torque."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import DataError, RobotModelError, TimestampError
from sensorless.estimation.momentum import MomentumDynamics, MomentumObserver
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot
from sensorless_studies.simulation.arm_push import Push, simulate_pushes
from sensorless.testing import perturbed_truth


@pytest.fixture(scope="module")
def ur5_truth():
    nom = load_robot("ur5")
    return nom, perturbed_truth(nom, rng=1)


@pytest.fixture(scope="module")
def pushed(ur5_truth):
    nom, truth = ur5_truth
    pushes = [Push(1.0, 2.0, (0.0, 0.0, -30.0), "tool0"), Push(3.0, 3.6, (20.0, 10.0, 0.0), "tool0")]
    traj, gt = simulate_pushes(truth, nom, pushes, duration=4.5, seed=3)
    st = ModelStructure(truth.robot, coulomb_smoothing=gt.coulomb_velocity)
    return traj, gt, MomentumDynamics(st, truth.parameters())


def _structures():
    """(name, structure, params, random state generator) for fixed base, floating base, transmission."""
    rng = np.random.default_rng(0)
    out = []
    nom = load_robot("ur5")
    st = ModelStructure(nom, coulomb_smoothing=0.05)
    p = st.prior()
    for j in nom.actuated_joints:
        p[st.joint_term_index(j, "fv")] = rng.uniform(0.1, 0.5)
        p[st.joint_term_index(j, "fc")] = rng.uniform(0.1, 1.0)
        p[st.joint_term_index(j, "offset")] = rng.uniform(-0.3, 0.3)
        p[st.joint_term_index(j, "armature")] = rng.uniform(0.05, 0.2)
    out.append(("ur5", st, p))
    solo = load_robot("solo12", floating_base=True)
    st = ModelStructure(solo, joint_terms=("fv", "fc", "armature"), coulomb_smoothing=0.03)
    p = st.prior()
    p[st.n_body_params:] = rng.uniform(0.01, 0.1, st.n_params - st.n_body_params)
    out.append(("solo12", st, p))
    from sensorless.robots.dvrk_psm import psm_structure

    st = psm_structure(drives="motors", coulomb_smoothing=0.05)
    p = np.zeros(st.n_params)
    for k in range(st.robot.n_bodies):  # a random physical body per identified link
        p[10 * k : 10 * k + 10] = pin.Inertia.Random().toDynamicParameters()
    p[st.n_body_params:] = rng.uniform(0.01, 0.2, st.n_params - st.n_body_params)
    out.append(("psm", st, p))
    return out


@pytest.mark.parametrize("case", _structures(), ids=lambda c: c[0])
def test_momentum_identity_matches_inverse_dynamics(case):
    """W(q, v, v̇) π = d/dt (M v) − β with β = Cᵀv − g − τ_f: Pinocchio's C, g and the
    identified joint/drive terms against the identification regressor (central difference in time)."""
    name, st, params = case
    dyn = MomentumDynamics(st, params)
    rng = np.random.default_rng(1)
    h = 1e-6
    for _ in range(3):
        if name == "psm":
            lo, hi = st.robot.position_limits()
            q = rng.uniform(lo, hi) * 0.5
            v, a = rng.normal(size=dyn.n) * 0.5, rng.normal(size=dyn.n)
            qs = [q + s * v + 0.5 * s * s * a for s in (h, -h)]
            Wpi = st.evaluate(q[None], v[None], a[None])[0] @ params
        else:
            model = st.robot.model
            q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq)) if name == "solo12" else \
                pin.randomConfiguration(model)
            v, a = rng.normal(size=dyn.n) * 0.5, rng.normal(size=dyn.n)
            qs = [pin.integrate(model, q, s * v + 0.5 * s * s * a) for s in (h, -h)]
            Wpi = st.evaluate(q[None], v[None], a[None])[0] @ params
        p_plus = dyn.mass_matrix(qs[0]) @ (v + h * a)
        p_minus = dyn.mass_matrix(qs[1]) @ (v - h * a)
        pdot = (p_plus - p_minus) / (2 * h)
        p, beta = dyn.momentum_terms(q, v)
        np.testing.assert_allclose(p, dyn.mass_matrix(q) @ v, atol=1e-12)
        rows = (pdot - beta)[st._row_idx] if name != "psm" else (pdot - beta)
        np.testing.assert_allclose(rows, Wpi, atol=1e-5 * (1 + np.abs(Wpi).max()))


@pytest.mark.parametrize("order", [1, 2])
def test_observer_recovers_known_push_noise_free(pushed, order):
    """Acceptance: RMS error of τ_ext ≤ 5 % of its peak (noise-free, pushed UR5, 1 kHz)."""
    traj, gt, dyn = pushed
    res = MomentumObserver(dyn, gain=100.0, order=order).run(traj)
    err = res.tau_ext - gt.tau_ext
    peak = np.abs(gt.tau_ext).max()
    assert peak > 5.0
    assert np.sqrt(np.mean(err**2)) <= 0.05 * peak
    big = np.abs(gt.tau_ext).max(axis=0) > 0.2 * peak  # per joint that feels the push
    per_joint = np.sqrt(np.mean(err[:, big] ** 2, axis=0)) / np.abs(gt.tau_ext[:, big]).max(axis=0)
    assert np.all(per_joint <= 0.05), per_joint
    # outside the pushes the observer stays near zero
    quiet = ~gt.active
    assert np.abs(res.tau_ext[quiet][200:]).max() < 0.1 * peak


def test_observer_with_wrong_model_is_biased(pushed, ur5_truth):
    """The oracle can fail: with the nominal (CAD) model and no friction the error is large."""
    traj, gt, _ = pushed
    nom, _ = ur5_truth
    st = ModelStructure(nom, joint_terms=())
    res = MomentumObserver(MomentumDynamics(st, st.prior()), gain=100.0).run(traj)
    err = res.tau_ext - gt.tau_ext
    assert np.sqrt(np.mean(err**2)) > 0.05 * np.abs(gt.tau_ext).max()


@pytest.mark.parametrize("order", [1, 2])
def test_streaming_step_equals_offline(pushed, order):
    traj, _, dyn = pushed
    part = traj.take(slice(900, 1300))
    off = MomentumObserver(dyn, gain=80.0, order=order).run(part)
    obs = MomentumObserver(dyn, gain=80.0, order=order, dt=part.dt)
    on = np.array([obs.step(part.q[i], part.v[i], part.tau[i]) for i in range(len(part))])
    np.testing.assert_allclose(on, off.r, atol=1e-9)


def test_observer_input_errors(pushed):
    traj, _, dyn = pushed
    part = traj.take(slice(0, 50))
    t = part.t.copy()
    t[20:] += 0.05
    with pytest.raises(TimestampError, match="sample 20"):
        MomentumObserver(dyn).run(part.with_(t=t))
    with pytest.raises(DataError, match="tau"):
        MomentumObserver(dyn).run(part.with_(tau=None))
    with pytest.raises(RobotModelError, match="gain"):
        MomentumObserver(dyn, gain=-1.0)
    with pytest.raises(RobotModelError, match="order"):
        MomentumObserver(dyn, order=3)
    with pytest.raises(TimestampError, match="dt"):
        MomentumObserver(dyn).step(part.q[0], part.v[0], part.tau[0])


def test_depth_first_renumbering_fixes_crba_on_psm_tree():
    """Regression: the PSM tree is not numbered depth-first, so pin.crba on it is wrong; the
    renumbered copy's M equals the RNEA columns of the original tree."""
    from sensorless.estimation.momentum import depth_first_model
    from sensorless.robots.dvrk_psm import psm_tree

    tree, _ = psm_tree()
    model = tree.model.copy()
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia.Random()
    data = model.createData()
    q = np.random.default_rng(0).uniform(-1, 1, model.nq)
    z = np.zeros(model.nv)
    M_rnea = np.array([pin.rnea(model, data, q, z, e) - pin.rnea(model, data, q, z, z) for e in np.eye(model.nv)]).T
    new, perm = depth_first_model(model)
    assert new is not model
    M_new = pin.crba(new, new.createData(), q[perm])
    M_new = np.triu(M_new) + np.triu(M_new, 1).T
    np.testing.assert_allclose(M_new, M_rnea[np.ix_(perm, perm)], atol=1e-10)
    ur5 = load_robot("ur5").model
    assert depth_first_model(ur5)[0] is ur5

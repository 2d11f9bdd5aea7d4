"""Stribeck velocity chosen from one compression pass (identification.stribeck): the candidate
equations contain the model's exactly, the projection criterion equals a direct least-squares
fit per candidate, and a known vs is recovered through identify()."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sensorless.errors import DataError
from sensorless.identification import identify
from sensorless.identification.stribeck import StribeckCandidates, choose_stribeck
from sensorless.regressor import ModelStructure, compress
from sensorless_studies.simulation.current_arm import truth_model

TERMS = ("fv", "fc", "stribeck", "offset", "armature")


@pytest.fixture(scope="module")
def arm():
    """A UR5 log with Stribeck friction on every joint (true vs known) and a little torque noise."""
    from sensorless.robot import load_robot
    from sensorless.data.trajectory import Trajectory

    robot = load_robot("ur5")
    rng = np.random.default_rng(3)
    t = np.arange(0, 30, 0.005)
    n = robot.n_actuated
    f = rng.uniform(0.05, 0.3, (3, n))
    ph = rng.uniform(0, 2 * np.pi, (3, n))
    amp = rng.uniform(0.3, 0.8, (3, n))
    q = sum(amp[k] * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    v = sum(amp[k] * 2 * np.pi * f[k] * np.cos(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    a = sum(-amp[k] * (2 * np.pi * f[k]) ** 2 * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(3))
    joints = list(robot.actuated_joints)
    vs_true = dict(zip(joints, rng.uniform(0.04, 0.12, n)))
    truth = ModelStructure(robot, joint_terms=TERMS, coulomb_smoothing=0.01, stribeck_velocity=vs_true)
    p = truth.prior()
    for j in joints:
        p[truth.joint_term_index(j, "fv")] = rng.uniform(0.5, 2)
        p[truth.joint_term_index(j, "fc")] = rng.uniform(1, 3)
        p[truth.joint_term_index(j, "stribeck")] = rng.uniform(1, 3)  # fs − fc
    traj = Trajectory(t=t, q=q, v=v, a=a, tau=np.zeros_like(q), joint_names=joints)
    tau = truth.torques(p, traj) + rng.normal(0, 0.02, q.shape)
    traj = dataclasses.replace(traj, tau=tau)
    return robot, truth, vs_true, traj


def _grid(vs_true):
    return {j: np.geomspace(0.01, 0.5, 21) * (vs / 0.0707) for j, vs in vs_true.items()}  # truth on the grid


def test_candidate_equations_contain_the_models_exactly(arm):
    robot, truth, vs_true, traj = arm
    grid = _grid(vs_true)
    cand = StribeckCandidates(dataclasses.replace(truth, stribeck_velocity=None), grid)
    ne_c = compress(cand, traj)
    choice = np.array([3, 10, 0, 20, 7, 15])
    s = cand.structure_for(choice)
    assert s.stribeck_velocity == {j: pytest.approx(grid[j][c]) for j, c in zip(robot.actuated_joints, choice)}
    ne = compress(s, traj)
    sel = cand.select(ne_c, choice)
    scale = np.abs(ne.A).max()
    assert np.abs(sel.A - ne.A).max() < 1e-10 * scale and np.allclose(sel.b, ne.b, rtol=1e-10, atol=1e-10 * scale)
    assert np.allclose(sel.c, ne.c) and sel.n_samples == ne.n_samples
    for drop in ([-1, 10, 0, -1, 7, 15], [-1] * 6):  # joints without a Stribeck term: zero column, or none
        s = cand.structure_for(np.array(drop))
        assert [j for j in robot.actuated_joints if "stribeck" in s.terms_of(j)] == \
            [j for j, c in zip(robot.actuated_joints, drop) if c >= 0]
        ne, sel = compress(s, traj), cand.select(ne_c, np.array(drop))
        assert sel.A.shape == ne.A.shape and np.abs(sel.A - ne.A).max() < 1e-10 * scale
        assert np.allclose(sel.b, ne.b, rtol=1e-10, atol=1e-10 * scale)


def test_projection_criterion_equals_a_direct_fit_per_candidate(arm):
    """SSE(w, vs) from the compressed equations (Frisch–Waugh–Lovell, and the left-out equations'
    quadratic) = the residual, on every sample, of an explicit least-squares fit with that width and
    Stribeck velocity to the samples the fit keeps (not those next to a reversal), on the base columns."""
    from sensorless.identification.base import base_parameters

    robot, truth, vs_true, traj = arm
    part = traj.chunks(2000).__next__()
    widths = {j: [0.003, 0.03] for j in robot.actuated_joints}
    cand = StribeckCandidates(truth, _grid(vs_true), widths)
    ne_c = compress(cand, part)
    choice, record = choose_stribeck(cand, ne_c, np.ones(robot.n_actuated))  # σ = 1: the plain residual
    assert np.all(choice[:, 1] >= 0)  # the truth has Stribeck friction on every joint
    k = 2
    j = robot.actuated_joints[k]
    ind = base_parameters(truth).independent

    def direct(c):
        s = cand.structure_for(c)
        keep = s.fit_mask(s.state(part)[1]).ravel() > 0  # the samples next to a reversal are left out of the fit
        assert 0.9 < keep.mean() < 1.0
        W, y = s.regressor(part), s.target(part).ravel()  # (N, rows, p)
        X = W.reshape(-1, W.shape[-1])[:, base_parameters(s).independent if s.per_joint_terms else ind]
        coef, *_ = np.linalg.lstsq(X[keep], y[keep], rcond=None)
        return float(np.sum((y - X @ coef) ** 2))  # scored on every sample

    for h in (0, 5, choice[k, 1]):
        c = choice.copy()
        c[k, 1] = h
        assert record[j]["sse"][h] == pytest.approx(direct(c), rel=1e-6)
    c = choice.copy()
    c[k, 1] = -1
    assert record[j]["sse_without"] == pytest.approx(direct(c), rel=1e-6)
    for g in range(3):  # the best per width is no worse than any candidate at that width
        c = choice.copy()
        c[k] = (g, choice[k, 1])
        assert record[j]["sse_width"][g] <= direct(c) * (1 + 1e-6)
    assert record[j]["vs"] == pytest.approx(cand.grid[k, choice[k, 1]])
    assert record[j]["widths"][0] == truth.smoothing_of(j)


def test_identify_recovers_the_true_stribeck_velocity_in_one_pass(arm):
    robot, truth, vs_true, traj = arm
    start = dataclasses.replace(truth, stribeck_velocity=None)
    res = identify(start, traj, stribeck_grid=_grid(vs_true))
    for j, vs in vs_true.items():
        assert res.structure.stribeck_velocity[j] == pytest.approx(vs, rel=0.21), j  # within one grid step
    assert set(res.diagnostics["stribeck_search"]) == set(vs_true)
    assert res.settings["stribeck_velocity"] == res.structure.stribeck_velocity
    assert res.train_metrics.nrmse.max() < 0.01


def test_grid_for_a_joint_without_a_stribeck_term_or_bad_values_is_refused(arm):
    robot, truth, vs_true, traj = arm
    no = ModelStructure(robot, joint_terms=("fv", "fc", "offset"))
    with pytest.raises(DataError, match="without a 'stribeck' term"):
        StribeckCandidates(no, {robot.actuated_joints[0]: [0.1]})
    with pytest.raises(DataError, match="finite and > 0"):
        StribeckCandidates(truth, {robot.actuated_joints[0]: [0.1, -1.0]})
    cand = StribeckCandidates(truth, _grid(vs_true))
    with pytest.raises(DataError, match="not compressed with this grid"):
        cand.select(compress(truth, traj.chunks(500).__next__()), np.zeros(robot.n_actuated, dtype=int))


def test_a_first_log_that_barely_moves_a_joint_does_not_shrink_its_grid(arm):
    """The candidates come from the first training log (the same on a cluster). On joint-wise logs
    that log barely moves the other joints; their grid is then scaled by the velocity limit."""
    from sensorless.identification.friction import GRID_SPEED_FLOOR, STRIBECK_GRID, friction_structure

    robot, truth, vs_true, traj = arm
    creep = dataclasses.replace(traj, v=traj.v * 1e-3, a=traj.a * 1e-3)
    joints = list(robot.actuated_joints)
    vlim = np.array([robot.model.velocityLimit[robot.v_index(j)] for j in joints])
    _, moving = friction_structure(truth, [traj], coulomb_smoothing=0.0)
    _, slow = friction_structure(truth, [creep], coulomb_smoothing=0.0)
    p95 = np.percentile(np.abs(traj.v), 95, axis=0)
    for k, j in enumerate(joints):
        top = STRIBECK_GRID[-1]
        assert max(moving.stribeck_grid[j]) == pytest.approx(top * max(p95[k], GRID_SPEED_FLOOR * vlim[k]))
        assert max(slow.stribeck_grid[j]) == pytest.approx(top * GRID_SPEED_FLOOR * vlim[k])


@pytest.mark.parametrize("fs_minus_fc", [0.0, -1.5])
def test_no_or_unphysical_stribeck_effect_drops_the_term(arm, fs_minus_fc):
    """A joint whose data show no Stribeck effect (fs = fc), or an unphysical one (fs < fc, friction
    rising at low speed), gets no Stribeck term: the search neither overfits noise nor fits a
    negative static-friction bump."""
    robot, truth, vs_true, traj = arm
    p = truth.prior()
    rng = np.random.default_rng(5)
    for j in robot.actuated_joints:
        p[truth.joint_term_index(j, "fv")] = 1.0
        p[truth.joint_term_index(j, "fc")] = 2.0
        p[truth.joint_term_index(j, "stribeck")] = fs_minus_fc
    log = dataclasses.replace(traj, tau=truth.torques(p, traj) + rng.normal(0, 0.02, traj.tau.shape))
    from sensorless.identification.friction_search import identify_friction

    res, fit = identify_friction(dataclasses.replace(truth, stribeck_velocity=None), [log], coulomb_smoothing=0.01)
    assert fit.stribeck_grid and not fit.stribeck_velocity  # searched on the default grid, kept nowhere
    assert all("stribeck" not in res.structure.terms_of(j) for j in robot.actuated_joints)
    assert all(r["vs"] is None for r in res.diagnostics["stribeck_search"].values())
    assert res.train_metrics.nrmse.max() < 0.02 if fs_minus_fc == 0 else True

"""The vectorised law choice (identification.stribeck.choose_stribeck) returns what the loop over
(width, vs) candidates with one SVD least squares per pair returned: the same choice, and the same
record to rounding, on simulated UR5 and Panda logs (σ estimated or given, with and without left-out
equations, fixed and searched vs, joints without fc or without a Stribeck term, laws dropped or kept),
also when every 2×2 system takes the SVD route. The loop is kept here as the oracle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sensorless.excitation import random_fourier
from sensorless.identification import stribeck
from sensorless.identification.base import base_parameters
from sensorless.identification.friction import friction_structure
from sensorless.identification.least_squares import two_step_sigma
from sensorless.identification.stribeck import MIN_STRIBECK_OVER_WIDTH, SWEEPS, StribeckCandidates, choose_stribeck
from sensorless.regressor import ModelStructure, compress
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory

TERMS = ("fv", "fc", "stribeck", "offset", "armature")


# ---- the oracle: choose_stribeck as it was before vectorisation (one lstsq per candidate pair) --------------
def _pinv_psd(A, rcond=1e-12):
    d = np.sqrt(np.maximum(np.diag(A), 0.0))
    d = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    lam, U = np.linalg.eigh(d[:, None] * A * d[None, :])
    keep = lam > rcond * max(float(lam.max(initial=0.0)), 1e-300)
    return (d[:, None] * (U[:, keep] / lam[keep]) @ U[:, keep].T) * d[None, :]


def _gain(R, beta, L, raw):
    RM, bM = L.T @ R @ L, L.T @ beta
    dRM = np.diag(RM)
    if np.any(dRM <= 1e-12 * np.maximum(np.abs(L).T @ raw, 1e-300)):
        return 0.0, np.zeros(L.shape[1])
    d = 1.0 / np.sqrt(dRM)
    coef = d * np.linalg.lstsq(d[:, None] * RM * d[None, :], d * bM, rcond=1e-12)[0]
    return float(bM @ coef), coef


def _left_out_score(Ao, bo, co, LX, theta_x0, U, Z):
    pi0 = LX @ theta_x0
    D = -LX @ U
    D[Z, np.arange(len(Z))] += 1.0
    AoD = Ao @ D
    s0 = float(pi0 @ Ao @ pi0 - 2.0 * bo @ pi0 + co)
    g = D.T @ (Ao @ pi0 - bo)
    H = D.T @ AoD
    return lambda tz: max(s0 + 2.0 * float(g @ tz) + float(tz @ H @ tz), 0.0)


def _finite(x):
    return [float(v) if np.isfinite(v) else None for v in np.ravel(x)]


def oracle(cand, ne, weights):
    s = cand.structure
    joints = list(s.robot.term_joints)
    n = len(joints)
    choice = np.zeros((n, 2), dtype=int)
    for k in range(n):
        choice[k, 1] = cand.vs_lists[k].size // 2 if cand.vs_lists[k].size else -1
    sigma = (np.asarray(weights, dtype=float) if isinstance(weights, np.ndarray)
             else two_step_sigma(cand.select(ne, choice)))
    A, b, c = ne.total(1.0 / sigma**2)
    Ao, bo, co = ne.left_out.total(1.0 / sigma**2) if ne.left_out is not None else (None, None, 0.0)
    ln_n = np.log(max(ne.n_samples, 2))
    base = base_parameters(s).independent
    nb, nt = cand.n_block_params, len(s.joint_terms)
    Gw = cand.widths.shape[1]
    record = {}
    for _ in range(SWEEPS):
        for k in np.flatnonzero(cand.searched):
            j = joints[k]
            cols = []
            for i in base:
                if i < nb:
                    cols.append({int(i): 1.0})
                    continue
                q, t = divmod(int(i) - nb, nt)
                term = s.joint_terms[t]
                if q == k and term in ("fc", "stribeck"):
                    continue
                vec = cand._term_vector(q, term, choice)
                if vec:
                    cols.append(vec)
            LX = np.zeros((cand.n_params, len(cols)))
            for m, vec in enumerate(cols):
                for i, a in vec.items():
                    LX[i, m] = a
            start = cand._start(k) + nt
            nw, ns = cand.width_lists[k].size, cand.vs_lists[k].size
            Z = np.concatenate([start + np.arange(nw), start + Gw + np.arange(ns)])
            AXX, AXZ, bX = LX.T @ A @ LX, LX.T @ A[:, Z], LX.T @ b
            P = _pinv_psd(AXX)
            U = P @ AXZ
            sse_x = c - bX @ P @ bX
            R = A[np.ix_(Z, Z)] - AXZ.T @ U
            beta = b[Z] - U.T @ bX
            raw = np.diag(A)[Z]
            left = _left_out_score(Ao, bo, co, LX, P @ bX, U, Z) if Ao is not None else None
            terms = s.terms_of(j)
            has_fc, has_st = "fc" in terms, "stribeck" in terms
            best = (np.inf, 0, -1)
            sse = np.full((nw, ns), np.inf)
            coef_st = np.zeros((nw, ns))
            sse_without = np.full(nw, np.inf)
            for g in range(nw):
                w = cand.width_lists[k][g]
                pen_w = ln_n * (g > 0)
                if has_fc and (not has_st or cand.vs_searched[k]):
                    L = np.zeros((nw + ns, 1))
                    L[g, 0] = 1.0
                    gain, coef = _gain(R, beta, L, raw)
                    sse_without[g] = sse_x - gain + (left(L @ coef) if left else 0.0)
                    if g == 0 or coef[0] > 0:
                        best = min(best, (sse_without[g] + pen_w, g, -1))
                for h in range(ns):
                    slow = cand.vs_lists[k][h] >= MIN_STRIBECK_OVER_WIDTH * w
                    L = np.zeros((nw + ns, 2 if has_fc else 1))
                    L[g, :] = 1.0
                    L[nw + h, -1] = -1.0
                    gain, coef = _gain(R, beta, L, raw)
                    sse[g, h], coef_st[g, h] = sse_x - gain + (left(L @ coef) if left else 0.0), coef[-1]
                    ok = slow and coef[-1] > 0 and (not has_fc or coef[0] >= 0)
                    if ok or not cand.vs_searched[k]:
                        best = min(best, (sse[g, h] + pen_w + 2 * ln_n * cand.vs_searched[k], g, h))
            if not np.isfinite(best[0]):
                best = (sse_x + (left(np.zeros(nw + ns)) if left else 0.0), 0, -1)
            choice[k] = best[1:]
            g = best[1]
            record[j] = {"grid": cand.vs_lists[k].tolist(), "widths": cand.width_lists[k].tolist(),
                         "sse": _finite(sse[g]), "sse_without": _finite([sse_without[g] if has_fc else sse_x])[0],
                         "coefficient": coef_st[g].tolist(),
                         "sse_width": _finite(np.minimum(sse.min(axis=1, initial=np.inf), sse_without)),
                         "vs": float(cand.vs_lists[k][best[2]]) if best[2] >= 0 else None,
                         "width": float(cand.width_lists[k][g]) if g > 0 else None,
                         "penalty_per_parameter": float(ln_n)}
    return choice, record


# ---- simulated logs ------------------------------------------------------------------------------------------
def _log(robot, seed, bump, tau_noise, n=1200, rate=200.0):
    """A Fourier log with true Coulomb friction plus a Stribeck bump (fs − fc) e^{−(v/vs)²} sgn v per
    joint (``bump``: {joint index: (fs − fc, vs)}), torque noise per joint, velocity noise 2e-3 rad/s."""
    truth = perturbed_truth(robot, rng=seed)
    motion = random_fourier(robot, rng=seed + 1, base_freq=0.2).sample(rate, n / rate)
    tr = synthetic_trajectory(truth, motion, noise_std=0.0, rng=seed)
    rng = np.random.default_rng(seed + 2)
    cols = [robot.joint_names.index(j) for j in robot.actuated_joints]
    tau = tr.tau.copy()
    for k, (dfs, vs) in bump.items():
        v = tr.v[:, robot.v_index(robot.actuated_joints[k])]
        tau[:, cols[k]] += dfs * np.exp(-(v / vs) ** 2) * np.sign(v)
    tau[:, cols] += rng.normal(size=(len(tr), len(cols))) * np.asarray(tau_noise)
    return dataclasses.replace(tr, tau=tau, v=tr.v + rng.normal(scale=2e-3, size=tr.v.shape))


def _candidates(structure, log, **kw):
    s, law = friction_structure(structure, [log], **kw)
    cand = StribeckCandidates(s, law.stribeck_grid, law.width_grid)
    return cand, compress(cand, log)


def _assert_same(new, ref):
    (c1, r1), (c0, r0) = new, ref
    assert np.array_equal(c1, c0) and c1.dtype == c0.dtype
    assert r1.keys() == r0.keys()
    for j in r0:
        assert r1[j].keys() == r0[j].keys()
        for key, want in r0[j].items():
            got = r1[j][key]
            if isinstance(want, list):
                assert len(got) == len(want), (j, key)
                assert [x is None for x in got] == [x is None for x in want], (j, key)
                got = [x for x in got if x is not None]
                want = [x for x in want if x is not None]
            else:
                assert (got is None) == (want is None), (j, key)
                got, want = ([], []) if want is None else ([got], [want])
            scale = max([abs(x) for x in want], default=0.0)  # (a coefficient near 0: to the field's scale)
            assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * scale), (j, key, got, want)


@pytest.fixture(scope="module")
def ur5():
    return load_robot("ur5")


@pytest.fixture(scope="module")
def ur5_case(ur5):
    """Stribeck bumps on 3 of 6 joints, torque noise from 0.005 to 0.2 N·m: the joints choose differently."""
    log = _log(ur5, 0, {0: (1.5, 0.15), 2: (0.8, 0.08), 4: (0.3, 0.2)}, [0.01, 0.2, 0.005, 0.05, 0.02, 0.1])
    return log, _candidates(ModelStructure(ur5, joint_terms=TERMS), log)


@pytest.mark.parametrize("weights", [None, "given"])
def test_the_ur5_choice_and_record_are_the_loops(ur5_case, weights):
    log, (cand, ne) = ur5_case
    assert ne.left_out is not None and cand.searched.all() and cand.vs_searched.all()
    w = np.array([0.02, 0.3, 0.01, 0.05, 0.03, 0.1]) if weights else None
    ref = oracle(cand, ne, w)
    _assert_same(choose_stribeck(cand, ne, w), ref)
    kept = ref[0][:, 1] >= 0
    assert kept.any() and not kept.all()  # some joints keep a Stribeck term, others drop it
    assert kept[0] and kept[2]  # the two largest true bumps are found


def test_without_left_out_equations(ur5_case):
    _, (cand, ne) = ur5_case
    ne = dataclasses.replace(ne, left_out=None)
    _assert_same(choose_stribeck(cand, ne, None), oracle(cand, ne, None))


def test_every_2x2_system_by_the_svd(ur5_case, monkeypatch):
    """With the closed-form route switched off every pair goes through the SVD least squares: same answer."""
    _, (cand, ne) = ur5_case
    monkeypatch.setattr(stribeck, "CLOSED_FORM_COND", 1.0)  # κ ≥ 1: no 2×2 system qualifies
    calls = []
    real = stribeck._gain
    monkeypatch.setattr(stribeck, "_gain", lambda *a: calls.append(1) or real(*a))
    _assert_same(choose_stribeck(cand, ne, None), oracle(cand, ne, None))
    assert len(calls) >= SWEEPS * cand.searched.sum() * cand.vs_lists[0].size  # the SVD route was taken


def test_fixed_vs_and_joints_without_fc_or_stribeck(ur5):
    """Joint 0 keeps a given vs (its width searched), joints 1 and 4 have a Stribeck term but no fc
    (joint 4's true bump is negative: no physical candidate, the term is dropped), joint 3 fc without a
    Stribeck term, joint 5 neither (not searched)."""
    joints = list(ur5.actuated_joints)
    per = {j: TERMS for j in joints}
    per[joints[1]] = ("fv", "stribeck", "offset", "armature")
    per[joints[3]] = ("fv", "fc", "offset", "armature")
    per[joints[4]] = per[joints[1]]
    per[joints[5]] = ("fv", "offset", "armature")
    log = _log(ur5, 3, {0: (1.0, 0.1), 1: (1.0, 0.1), 2: (0.5, 0.1), 4: (-1.0, 0.1)}, 0.02)
    st = ModelStructure(ur5, joint_terms=per, stribeck_velocity={joints[0]: 0.05})
    s, law = friction_structure(st, [log])
    grid = {j: g for j, g in law.stribeck_grid.items() if j != joints[0]}
    grid[joints[4]] = [0.05, 0.1, 0.2]  # around the true vs (ε only)
    widths = {j: g for j, g in law.width_grid.items() if j != joints[4]}
    cand = StribeckCandidates(dataclasses.replace(s, stribeck_velocity={**s.stribeck_velocity, joints[0]: 0.05}),
                              grid, widths)
    assert not cand.vs_searched[0] and cand.searched[0] and not cand.searched[5]
    ne = compress(cand, log)
    for w in (None, np.full(6, 0.02)):
        ref = oracle(cand, ne, w)
        _assert_same(choose_stribeck(cand, ne, w), ref)
        assert ref[0][0, 1] == 0 and ref[1][joints[0]]["vs"] == pytest.approx(0.05)  # the fixed vs is kept
        assert ref[0][1, 1] >= 0 and ref[0][4].tolist() == [0, -1]


def test_a_log_without_stribeck_effect(ur5):
    """Most joints drop the term (the drop branch of the choice)."""
    log = _log(ur5, 5, {}, 0.02)
    cand, ne = _candidates(ModelStructure(ur5, joint_terms=TERMS), log)
    ref = oracle(cand, ne, None)
    _assert_same(choose_stribeck(cand, ne, None), ref)
    assert (ref[0][:, 1] < 0).sum() >= 3


def test_the_panda_choice_and_record_are_the_loops():
    panda = load_robot("panda")
    noise = [0.02, 0.05, 0.01, 0.1, 0.02, 0.005, 0.01, 0.01, 0.01][:panda.n_actuated]
    log = _log(panda, 7, {1: (2.0, 0.1), 3: (1.0, 0.05), 6: (0.2, 0.1)}, noise, n=1000)
    cand, ne = _candidates(ModelStructure(panda, joint_terms=TERMS), log)
    for w in (None, np.full(cand.n_rows, 0.05)):
        _assert_same(choose_stribeck(cand, ne, w), oracle(cand, ne, w))


def test_the_edges_of_the_admissibility_rules(ur5):
    """Explicit grids on the edges of the rules: joint 0's true vs is exactly 3 ε (vs ≥ 3 w admits it),
    joint 1 has a negative Coulomb coefficient and a Stribeck bump (the bump is not admitted with fc < 0;
    the simpler law at ε is, whatever its sign),
    joints 3-5 keep a fixed vs, joint 3's fitting a negative bump (kept whatever its sign)."""
    joints = list(ur5.actuated_joints)
    s, law = friction_structure(ModelStructure(ur5, joint_terms=TERMS), [_log(ur5, 11, {}, 0.02)])
    eps = [s.smoothing_of(j) for j in joints]
    log = _log(ur5, 11, {0: (1.5, 3 * eps[0]), 1: (0.3, 0.1), 2: (1.0, 0.1), 3: (-0.5, 0.1)}, 0.02)
    truth_fc1 = perturbed_truth(ur5, rng=11).fc[1]
    log.tau[:, ur5.joint_names.index(joints[1])] -= 1.3 * truth_fc1 * np.sign(log.v[:, ur5.v_index(joints[1])])
    grid = {joints[0]: [3 * eps[0], 10 * eps[0], 30 * eps[0]], joints[1]: [0.05, 0.1, 0.2], joints[2]: [0.05, 0.1, 0.3]}
    st = dataclasses.replace(s, stribeck_velocity={**s.stribeck_velocity, joints[3]: 0.1})
    cand = StribeckCandidates(st, grid, {j: [2 * e] for j, e in zip(joints, eps)})
    ne = compress(cand, log)
    ref = oracle(cand, ne, None)
    _assert_same(choose_stribeck(cand, ne, None), ref)
    choice, rec = ref
    assert choice[0].tolist() == [0, 0]  # vs = 3 ε exactly: admitted and best
    assert choice[1].tolist() == [0, -1] and max(rec[joints[1]]["coefficient"]) > 0  # a bump fitted, not admitted
    assert choice[2, 1] == 1
    assert not cand.vs_searched[3:].any() and choice[3, 1] == 0 and rec[joints[3]]["coefficient"][0] < 0

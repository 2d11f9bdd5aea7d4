"""model.urdf's prior-mass SDP on Clarabel's own API (identification/prior_projection.py) against the
cvxpy formulation it replaced (issue 28; the oracle, copied below): Clarabel's svec convention, the same
conic data as cvxpy compiled, the same minimisers on the UR5 and Panda priors (consistent parameters
moved along seen and unseen directions, fixed subsets, with and without a target) and the same refusals."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from sensorless.identification.base import base_parameters
from sensorless.identification.prior_projection import conic_data, solve_prior_projection, svec
from sensorless.parameters import pseudo_inertia, pseudo_inertia_basis
from sensorless.regressor import ModelStructure
from sensorless.testing import perturbed_truth

cp = pytest.importorskip("cvxpy")


def _cvxpy_problem(pi, B, S, fix, m0, target=None):
    """The program as urdf_values wrote it with cvxpy until issue 28: ``(problem, y)``."""
    basis16 = pseudo_inertia_basis().reshape(10, 16).T
    y = cp.Variable(len(pi))
    x = (pi / S) + y
    cons = [(B * S[None, :]) @ y == 0, x[fix * 10] == m0 / S[fix * 10]]
    for k in range(len(pi) // 10):
        J = cp.reshape(basis16 @ x[10 * k:10 * k + 10], (4, 4), order="C")
        cons.append(0.5 * (J + J.T) >> 0)
    return cp.Problem(cp.Minimize(cp.sum_squares(y if target is None else x - target / S)), cons), y


def _cvxpy_step(pi, B, S, fix, m0, target=None):
    prob, y = _cvxpy_problem(pi, B, S, fix, m0, target)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            prob.solve(solver=cp.CLARABEL)
    except (cp.error.SolverError, ValueError, ArithmeticError):
        return None
    return None if prob.status != cp.OPTIMAL or y.value is None else np.asarray(y.value)


def _program(robot):
    """The prior, B (standard → base) and the scales S as urdf_values builds them."""
    pi0 = robot.inertial_parameters()
    n = len(pi0)
    B = base_parameters(ModelStructure(robot)).B[:, :n]
    m = np.where(pi0[::10] > 0, pi0[::10], max(pi0[::10].mean(), 1e-3))
    S = np.repeat(m, 10) * np.tile([1, 0.1, 0.1, 0.1] + [0.01] * 6, n // 10)
    return pi0, B, S


def test_svec_is_clarabels_psd_triangle_packing():
    """Projecting svec(M) onto Clarabel's PSDTriangleConeT(4) gives svec of M's eigenvalue-clipped
    projection: the packing's order and √2 scaling are the ones Clarabel uses."""
    import clarabel
    import scipy.sparse as sp

    rng = np.random.default_rng(0)
    for _ in range(5):
        G = rng.normal(size=(4, 4))
        M = G + G.T
        w, Q = np.linalg.eigh(M)
        proj = (Q * np.maximum(w, 0)) @ Q.T
        s = clarabel.DefaultSettings()
        s.verbose = False
        eye = sp.identity(10, format="csc")
        sol = clarabel.DefaultSolver(2.0 * eye, -2.0 * svec(M), -eye, np.zeros(10), [clarabel.PSDTriangleConeT(4)], s).solve()
        assert sol.status == clarabel.SolverStatus.Solved
        assert np.allclose(sol.x, svec(proj), atol=1e-7)
        H = rng.normal(size=(4, 4))
        assert np.isclose(svec(M) @ svec(H + H.T), np.trace(M @ (H + H.T)))


@pytest.mark.parametrize("target", [False, True])
def test_conic_data_is_what_cvxpy_compiled(ur5, target):
    pi0, B, S = _program(ur5)
    pi = perturbed_truth(ur5, rng=0).robot.inertial_parameters()
    fix = np.array([1, 4])
    t = pi0 if target else None
    data = _cvxpy_problem(pi, B, S, fix, pi0[10 * fix], t)[0].get_problem_data(cp.CLARABEL)[0]
    P, q, A, b, (n_zero, n_psd) = conic_data(pi, B, S, fix, pi0[10 * fix], t)
    assert (data["dims"].zero, list(data["dims"].psd)) == (n_zero, [4] * n_psd)
    assert A.nnz == data["A"].nnz and np.array_equal(A.toarray(), data["A"].toarray())
    assert np.array_equal(b, data["b"]) and np.array_equal(q, data["c"])
    assert np.array_equal(P.toarray(), data["P"].toarray())


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_minimiser_and_refusals_equal_cvxpy(request, name):
    robot = request.getfixturevalue(name)
    pi0, B, S = _program(robot)
    nb = len(pi0) // 10
    N = np.linalg.svd(B)[2][np.linalg.matrix_rank(B):].T  # directions no torque log sees
    solved = refused = 0
    for seed in (0, 1):
        rng = np.random.default_rng(seed)
        truth = perturbed_truth(robot, rng=seed).robot.inertial_parameters()
        for scale in (0.1, 0.5):  # S·N z is seen in part (B S N ≠ 0): at 0.5 often no physical bodies remain
            pi = truth + scale * S * (N @ rng.normal(size=N.shape[1]))
            cases = [(np.arange(0), None), (np.arange(0), pi0), (np.arange(nb), None), (np.arange(nb), pi0),
                     (rng.choice(nb, 2, replace=False), None), (rng.choice(nb, 3, replace=False), pi0)]
            for fix, target in cases:
                new = solve_prior_projection(pi, B, S, fix, pi0[10 * fix], target=target)
                old = _cvxpy_step(pi, B, S, fix, pi0[10 * fix], target)
                assert (new is None) == (old is None), (seed, scale, fix, target is None)
                if new is None:
                    refused += 1
                    continue
                solved += 1
                out = pi + S * new
                assert np.abs(S * (new - old)).max() <= 1e-8 * np.abs(pi + S * old).max()
                assert np.abs(B @ (out - pi)).max() <= 1e-6 * np.abs(B @ pi).max()
                assert np.allclose(out[10 * fix], pi0[10 * fix], rtol=1e-6)
                assert np.linalg.eigvalsh(pseudo_inertia((out / S).reshape(-1, 10))).min() > -1e-6
    assert solved and refused  # both outcomes are exercised


def test_an_unphysical_mass_or_non_finite_data_is_refused_by_both(ur5):
    pi0, B, S = _program(ur5)
    fix, m0 = np.array([2]), np.array([-1.0])
    assert solve_prior_projection(pi0, B, S, fix, m0) is None
    assert _cvxpy_step(pi0, B, S, fix, m0) is None
    assert solve_prior_projection(pi0, B, S, fix, pi0[[20]]) is not None
    for bad in (np.nan, np.inf):
        pi = pi0.copy()
        pi[13] = bad  # Clarabel alone would drop the rows and report Solved
        assert solve_prior_projection(pi, B, S, fix, pi0[[20]]) is None
        assert solve_prior_projection(pi0, B, S, fix, pi0[[20]], target=pi) is None
        with np.errstate(invalid="ignore"):
            assert _cvxpy_step(pi, B, S, fix, pi0[[20]]) is None

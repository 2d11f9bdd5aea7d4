"""Least-squares solvers on normal equations: a column that no sample excites may sum to a tiny
negative diagonal (combinations of candidate columns, or folds summed in another order). It is
a dead column like an exact zero, not a NaN that voids every column."""

from __future__ import annotations

import numpy as np

from sensorless.identification.least_squares import solve_truncated_svd, two_step_sigma
from sensorless.regressor.normal_equations import NormalEquations


def _equations(dead_diagonal: float) -> NormalEquations:
    rng = np.random.default_rng(0)
    rows, p, n = 2, 5, 400
    ne = NormalEquations.zeros(rows, p)
    truth = rng.normal(size=p)
    truth[3] = 0.0
    for _ in range(n):
        W = rng.normal(size=(rows, p))
        W[:, 3] = 0.0  # never excited
        ne.add(W[None], (W @ truth + 0.01 * rng.normal(size=rows))[None])
    ne.A[:, 3, 3] = dead_diagonal  # what summing round-off leaves of a zero column
    return ne


def test_a_dead_column_with_a_negative_round_off_diagonal_is_dead_not_nan():
    exact, noisy = _equations(0.0), _equations(-9e-13)
    (pa, ra), (pb, rb) = solve_truncated_svd(exact), solve_truncated_svd(noisy)
    assert ra == rb == 4 and np.all(np.isfinite(pb))
    np.testing.assert_allclose(pb, pa, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(two_step_sigma(noisy), two_step_sigma(exact), rtol=1e-12)
    assert np.all(two_step_sigma(noisy) < 0.02)  # the 0.01 noise, not a failed fit

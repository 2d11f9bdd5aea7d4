"""Ordinary and weighted least squares on compressed normal equations.

With the base regressor W₁ (independent columns), the (weighted) problem

    min_πb Σ_r w_r ‖W₁,r π_b − y_r‖²,   w_r = 1/σ_r²

has normal equations (Σ_r w_r A_r[ind, ind]) π_b = Σ_r w_r b_r[ind]. Columns are
equilibrated (D = diag(A₁₁)^-½) before the solve; the condition number reported is
that of the equilibrated base regressor, cond(W₁ D) = sqrt(cond(D A₁₁ D)).
``weights="auto"`` estimates σ_r from the OLS residual of row r and refits (iterated two-step
WLS, :data:`AUTO_WEIGHT_ITERATIONS` fits; no second pass over the data thanks to per-row
normal equations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ExcitationError, SolverError
from ..regressor.normal_equations import NormalEquations
from .base import BaseParameters

__all__ = ["LeastSquaresSolution", "solve_least_squares", "solve_truncated_svd", "condition_number", "excitation_check",
           "sample_count_check", "two_step_sigma", "row_weights", "joint_term_inflation"]

# Below this ratio of smallest to largest singular value of the equilibrated base
# regressor, a direction of parameter space is considered not excited by the data.
MIN_SINGULAR_RATIO = 1e-6
# weights="auto": fits in all (the unweighted one, then refits with σ_r of the previous fit)
AUTO_WEIGHT_ITERATIONS = 3


@dataclass
class LeastSquaresSolution:
    base_values: np.ndarray
    row_weights: np.ndarray
    sigma: np.ndarray  # per-row residual standard deviation
    condition_number: float
    base_covariance_diag: np.ndarray  # σ̂² diag((W₁ᵀ Σ⁻¹ W₁)⁻¹)


def _base_system(ne: NormalEquations, base: BaseParameters, w: np.ndarray):
    A, b, c = ne.total(w)
    ind = base.independent
    return A[np.ix_(ind, ind)], b[ind], c


def sample_count_check(ne: NormalEquations, base: BaseParameters, w: np.ndarray | None = None) -> None:
    """ExcitationError when the samples give fewer equations than there are base parameters."""
    w = np.ones(ne.A.shape[0]) if w is None else w
    n_eq = ne.n_samples * int(np.count_nonzero(w))
    if n_eq < base.rank:
        raise ExcitationError(
            f"too few samples: {ne.n_samples} samples give {n_eq} equations for {base.rank} base parameters; "
            "log more data"
        )


def _equilibrated_spectrum(ne: NormalEquations, base: BaseParameters, w: np.ndarray):
    """Of the column-equilibrated base normal matrix D A₁₁ D: the unexcited columns (indices
    into the base parameters), then its singular values √λ (ascending) and eigenvectors (both
    None when a column is unexcited)."""
    A11, _, _ = _base_system(ne, base, w)
    if not np.all(np.isfinite(A11)):
        raise SolverError("the normal equations are not finite; check the data for extreme values")
    d = np.sqrt(np.maximum(np.diag(A11), 0.0))  # a column that is zero can sum to -1e-13
    dead = np.flatnonzero(d <= 1e-12 * max(d.max(), 1e-300))
    if dead.size:
        return dead, None, None
    try:
        evals, evecs = np.linalg.eigh(A11 / np.outer(d, d))
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"eigen-decomposition of the normal equations failed ({exc})") from None
    return dead, np.sqrt(np.maximum(evals, 0.0)), evecs


def condition_number(ne: NormalEquations, base: BaseParameters, w: np.ndarray | None = None) -> float:
    """Condition number of the equilibrated base regressor, whatever the method (inf when a
    base parameter is not excited at all); :func:`excitation_check` also refuses a bad one."""
    w = np.ones(ne.A.shape[0]) if w is None else w
    dead, sv, _ = _equilibrated_spectrum(ne, base, w)
    return float("inf") if dead.size else float(sv[-1] / max(sv[0], 1e-300))


def excitation_check(ne: NormalEquations, base: BaseParameters, w: np.ndarray | None = None) -> float:
    """Condition number of the equilibrated base regressor; ExcitationError if rank deficient."""
    w = np.ones(ne.A.shape[0]) if w is None else w
    sample_count_check(ne, base, w)
    dead, sv, evecs = _equilibrated_spectrum(ne, base, w)
    labels = [base.labels[k] for k in base.independent]
    if dead.size:
        names = ", ".join(labels[k] for k in dead[:5])
        raise ExcitationError(
            f"the data do not excite {dead.size} base parameter(s) at all (e.g. {names}); "
            "move those joints or remove the term"
        )
    if sv[0] < MIN_SINGULAR_RATIO * sv[-1]:
        bad = np.argsort(-np.abs(evecs[:, 0]))[:3]
        names = ", ".join(labels[k] for k in bad)
        raise ExcitationError(
            f"rank-deficient excitation: the base regressor's condition number is {sv[-1] / max(sv[0], 1e-300):.3g}; "
            f"the least-excited direction involves {names}. Use a richer trajectory "
            "(e.g. `sensorless excite`), more data, or fewer joint terms; or fit with method lmi (the prior "
            "fills the unexcited directions) or svd (minimum norm)"
        )
    return float(sv[-1] / sv[0])


def _solve(A11: np.ndarray, b1: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.maximum(np.diag(A11), 0.0))  # a column that is zero can sum to -1e-13
    d[d == 0] = 1.0
    S = A11 / np.outer(d, d)
    try:
        z = np.linalg.solve(S, b1 / d)
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"least-squares solve failed ({exc}); the excitation is probably too poor") from None
    if not np.all(np.isfinite(z)):
        raise SolverError("least-squares solve returned non-finite values; check the data for extreme values")
    return z / d


def solve_least_squares(
    ne: NormalEquations,
    base: BaseParameters,
    weights: str | np.ndarray | None = None,
) -> LeastSquaresSolution:
    """OLS (``weights=None``), WLS with given per-row σ (array), or two-step WLS (``"auto"``)."""
    rows = ne.A.shape[0]
    w = np.ones(rows)
    if isinstance(weights, np.ndarray) or (weights is not None and not isinstance(weights, str)):
        sigma = np.asarray(weights, dtype=float)
        if sigma.shape != (rows,) or np.any(sigma <= 0):
            raise SolverError(f"weights must be {rows} positive per-joint noise levels σ, got {sigma}")
        w = 1.0 / sigma**2
    cond = excitation_check(ne, base, w)
    A11, b1, _ = _base_system(ne, base, w)
    pi_b = _solve(A11, b1)
    params = np.zeros(ne.A.shape[1])
    params[base.independent] = pi_b
    if isinstance(weights, str):
        if weights != "auto":
            raise SolverError(f"unknown weights '{weights}'; use None, 'auto' or per-joint σ values")
        for _ in range(AUTO_WEIGHT_ITERATIONS - 1):  # iterated two-step (see two_step_sigma)
            w = 1.0 / _sigma_floor(ne, np.sqrt(ne.residual_ss(params) / max(ne.n_samples, 1))) ** 2
            cond = excitation_check(ne, base, w)
            A11, b1, _ = _base_system(ne, base, w)
            pi_b = _solve(A11, b1)
            params[base.independent] = pi_b
    sigma = np.sqrt(ne.residual_ss(params) / max(ne.n_samples - base.rank / rows, 1))
    # covariance of π_b under the weighted model: (W₁ᵀ Σ⁻¹ W₁)⁻¹ with Σ = diag(σ_r²)
    A11_s, _, _ = _base_system(ne, base, 1.0 / np.maximum(sigma, 1e-12) ** 2)
    try:
        cov_diag = np.diag(np.linalg.pinv(A11_s, hermitian=True))
    except np.linalg.LinAlgError:
        cov_diag = np.full(base.rank, np.nan)
    return LeastSquaresSolution(pi_b, w, sigma, cond, cov_diag)


def solve_truncated_svd(ne: NormalEquations, rcond: float = 1e-6, row_weights: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Minimum-norm least squares on all standard parameters by truncated SVD.

    With D = diag(A)^-½, S = D A D = U Λ Uᵀ, keep the directions with √λ > rcond·√λ_max:
    π = D U_r Λ_r⁻¹ U_rᵀ D b. No base-parameter structure and no physical constraint: this
    is the "SVD" baseline of the contact-identification literature, tolerant of directions a
    gait leaves unexcited. Returns (π, numerical rank).
    """
    A, b, _ = ne.total(row_weights)
    d = np.sqrt(np.maximum(np.diag(A), 0.0))  # a column that is zero can sum to -1e-13 (combined candidates)
    live = d > 1e-12 * max(d.max(), 1e-300)
    d[~live] = 1.0
    S = A / np.outer(d, d)
    S[~live, :] = 0.0
    S[:, ~live] = 0.0
    if not np.all(np.isfinite(S)):
        raise SolverError("the normal equations are not finite; check the data for extreme values")
    try:
        lam, U = np.linalg.eigh(S)
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"eigen-decomposition of the normal equations failed ({exc})") from None
    lam = np.maximum(lam, 0.0)
    keep = np.sqrt(lam) > rcond * np.sqrt(lam.max())
    if not keep.any():
        raise ExcitationError("the data excite no parameter at all")
    z = U[:, keep] @ ((U[:, keep].T @ (b / d)) / lam[keep])
    return z / d, int(keep.sum())


def two_step_sigma(ne: NormalEquations, rcond: float = MIN_SINGULAR_RATIO, iterations: int = AUTO_WEIGHT_ITERATIONS) -> np.ndarray:
    """Per-row noise σ_r of two-step weighted fitting, from the unconstrained fit's residual.

    ``σ_r² = ‖W_r π̂ − y_r‖² / (N − rank/rows)`` with ``π̂`` the minimum-norm least-squares
    solution over all standard parameters (:func:`solve_truncated_svd`, so a rank-deficient
    excitation is fine), floored as :func:`_sigma_floor`. Each further iteration refits with
    weights ``1/σ_r²`` and re-estimates σ (iterated feasible GLS, default 3 fits): on a short
    log the unweighted fit leaves the big joints' noise in the small joints' residual (UR5,
    600 samples: wrist σ over-estimated 2–6×; the second fit is within a few %). Works from the
    compressed equations alone (per-row normal equations); no second pass over the data.
    """
    rows = ne.A.shape[0]
    w = None
    for _ in range(max(int(iterations), 1)):
        params, rank = solve_truncated_svd(ne, rcond=rcond, row_weights=w)
        dof = max(ne.n_samples - rank / max(rows, 1), 1.0)
        sig = _sigma_floor(ne, np.sqrt(np.maximum(ne.residual_ss(params), 0.0) / dof))
        w = 1.0 / sig**2
    return sig


def _sigma_floor(ne: NormalEquations, sig: np.ndarray) -> np.ndarray:
    """σ_r ≥ max(1e-6 RMS(y_r), 1e-6 max_r σ_r): a residual at the level of round-off in
    ``‖Wπ‖² − 2bᵀπ + c`` (noise-free data) says nothing about noise, and weights that far apart
    would only spoil the conditioning."""
    rms = np.sqrt(np.maximum(ne.c, 0.0) / max(ne.n_samples, 1))
    return np.maximum(sig, np.maximum(1e-6 * rms, 1e-6 * max(float(sig.max()), 1e-12)))


def row_weights(ne: NormalEquations, weights: str | np.ndarray | None) -> np.ndarray | None:
    """Row weights ``w_r = 1/σ_r²``: None (unweighted), ``"auto"`` (:func:`two_step_sigma`)
    or per-row σ values (checked positive and finite by the caller)."""
    if weights is None:
        return None
    if isinstance(weights, str):
        if weights != "auto":
            raise SolverError(f"unknown weights '{weights}'; use None, 'auto' or per-joint σ values")
        return 1.0 / two_step_sigma(ne) ** 2
    return 1.0 / np.asarray(weights, dtype=float) ** 2


def joint_term_inflation(ne: NormalEquations, base: BaseParameters, w: np.ndarray | None = None,
                         n_body_params: int | None = None) -> dict[str, float]:
    """Variance inflation factor of every joint-term base parameter (label → VIF).

    With ``S = D A₁₁ D`` the equilibrated (weighted) base normal matrix, ``VIF_k = (S⁻¹)_kk =
    1 / (1 − R_k²)``, ``R_k²`` the fraction of column ``k`` that the other base columns explain
    on this log. A VIF of 10³ means the term's effect is 99.9 % collinear with the others: the
    log cannot tell it apart, and its estimate (and predictions off this log) swing with the noise.
    Joint-term columns are the independent columns at index ≥ ``n_body_params``.
    """
    w = np.ones(ne.A.shape[0]) if w is None else w
    A11, _, _ = _base_system(ne, base, w)
    d = np.sqrt(np.maximum(np.diag(A11), 0.0))  # a column that is zero can sum to -1e-13
    live = d > 1e-12 * max(d.max(), 1e-300)
    d[~live] = 1.0
    S = A11 / np.outer(d, d)
    try:
        inv = np.linalg.pinv(S, hermitian=True, rcond=1e-14)
    except np.linalg.LinAlgError:
        return {}
    nb = n_body_params if n_body_params is not None else 0
    out = {}
    for i, k in enumerate(base.independent):
        if k >= nb and live[i]:
            out[base.labels[k]] = float(inv[i, i])
    return out

"""identify(): robot + logs → physically interpretable dynamic model.

Pipeline: ModelStructure (columns/rows) → streaming compression → base parameters →
solver → standard parameters → IdentificationResult.
"""

from __future__ import annotations

import time
import warnings
from typing import Callable, Iterable, Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import SolverError
from ..regressor.compress import NormalEquations, compress
from ..regressor.terms import ModelStructure
from ..robot import Robot
from .base import BaseParameters, base_parameters
from .least_squares import solve_least_squares, solve_truncated_svd
from .metrics import metrics_from_sums
from .result import IdentificationResult

__all__ = ["identify", "METHODS"]

METHODS = ("ols", "wls", "svd", "lmi")


def identify(
    model: Robot | ModelStructure,
    data: Trajectory | Iterable[Trajectory] | NormalEquations,
    *,
    method: str = "ols",
    weights: str | Sequence[float] | None = None,
    joint_terms: Sequence[str] = ("fv", "fc", "offset", "armature"),
    standard: str = "closest_to_prior",
    chunk: int = 2048,
    svd_rcond: float = 1e-6,
    gamma: float | str = 1e-3,
    regularization: str | None = "pullback",
    prior: np.ndarray | None = None,
    ellipsoids=None,
    lmi_options: dict | None = None,
    progress: Callable[[int], None] | None = None,
) -> IdentificationResult:
    """Identify base and standard parameters from trajectories (or precompressed equations).

    ``method``: "ols" or "wls" (two-step WLS with per-joint σ unless ``weights`` gives σ),
    or "svd" (minimum-norm truncated SVD over all standard parameters, relative cut-off
    ``svd_rcond``; the unconstrained baseline for contact identification), or "lmi"
    (physically consistent convex program, :func:`~.lmi.solve_lmi`, regularised toward
    ``prior`` — default the model's own inertials — with ``regularization`` and weight
    ``gamma``; ``gamma="auto"`` picks it by 5-fold cross-validation on the training data,
    :func:`~.lmi.cross_validate_gamma`). ``ellipsoids`` and ``lmi_options`` go to the solver.
    ``standard``: how to pick standard parameters from the base ones, "closest_to_prior"
    (nearest to the model's own inertials) or "min_norm".
    """
    if method not in METHODS:
        raise SolverError(f"unknown method '{method}'; choose from {METHODS}")
    structure = model if isinstance(model, ModelStructure) else ModelStructure(model, joint_terms=tuple(joint_terms))
    prior_note = None
    if method == "lmi" and prior is None and regularization is not None and _massless_prior(structure):
        regularization, gamma = None, 0.0  # a pull toward zero mass everywhere is no prior
        prior_note = (f"'{structure.robot.name}' has no inertial prior (every identified body is massless): "
                      "ran without regularisation (regularization=None, gamma=0); pass prior=... to regularise")
        warnings.warn(prior_note, stacklevel=2)
    if method == "lmi" and gamma == "auto":
        if isinstance(data, NormalEquations):
            raise SolverError("gamma='auto' needs the training trajectories, not precompressed equations")
        data = [data] if isinstance(data, Trajectory) else list(data)
    t0 = time.perf_counter()
    ne = data if isinstance(data, NormalEquations) else compress(structure, data, chunk=chunk, progress=progress)
    t_compress = time.perf_counter() - t0
    base = base_parameters(structure)
    t1 = time.perf_counter()
    w = weights
    if method == "wls" and w is None:
        w = "auto"
    if w is not None and not isinstance(w, str):
        w = np.asarray(w, dtype=float)
    if method == "svd":
        params, svd_rank = solve_truncated_svd(ne, rcond=svd_rcond)
        base_values = base.base(params)
        sigma = np.sqrt(ne.residual_ss(params) / max(ne.n_samples, 1))
        extra = {"svd_rank": svd_rank, "svd_rcond": svd_rcond}
        cond, base_std = float("nan"), []
    elif method == "lmi":
        from .lmi import cross_validate_gamma, solve_lmi

        opts = dict(lmi_options or {})
        row_w = None if w is None or isinstance(w, str) else 1.0 / np.asarray(w) ** 2
        extra = {}
        if gamma == "auto":
            cv = cross_validate_gamma(structure, data, period="auto", prior=prior, regularization=regularization,
                                      ellipsoids=ellipsoids, row_weights=row_w, **opts)
            gamma = cv.gamma
            extra["gamma_selection"] = cv.to_dict()
        lmi = solve_lmi(ne, structure, base=base, prior=prior, regularization=regularization, gamma=float(gamma),
                        ellipsoids=ellipsoids, row_weights=row_w, **opts)
        params = lmi.params
        base_values = base.base(params)
        sigma = np.sqrt(ne.residual_ss(params) / max(ne.n_samples, 1))
        cond, base_std = float("nan"), []
        extra["lmi"] = lmi.summary()
        extra["gamma"] = float(gamma)
        if prior_note:
            extra["prior_note"] = prior_note
    else:
        sol = solve_least_squares(ne, base, w)
        params = _standard(base, sol.base_values, structure, standard)
        base_values, sigma, cond = sol.base_values, sol.sigma, sol.condition_number
        base_std = np.sqrt(np.maximum(sol.base_covariance_diag, 0)).tolist()
        extra = {}
    t_solve = time.perf_counter() - t1
    train = metrics_from_sums(
        structure.row_names, ne.residual_ss(params), ne.c, ne.y_max - ne.y_min, ne.n_samples
    )
    diagnostics = {
        "rank": base.rank,
        "n_standard": structure.n_params,
        "condition_number": cond,
        "n_samples": ne.n_samples,
        "residual_sigma": dict(zip(structure.row_names, map(float, sigma))),
        "base_std": base_std,
        **extra,
        "compress_seconds": t_compress,
        "solve_seconds": t_solve,
    }
    settings = {
        "method": method,
        "weights": w.tolist() if isinstance(w, np.ndarray) else w,
        "standard": standard,
        "chunk": chunk,
        **({"gamma": float(gamma), "regularization": regularization, "prior": "given" if prior is not None else "model"}
           if method == "lmi" else {}),
        **structure.settings(),
    }
    return IdentificationResult(method, structure, base, base_values, params, {"svd": "min_norm_svd", "lmi": "lmi"}.get(method, standard), train, diagnostics, settings)


def _massless_prior(structure: ModelStructure) -> bool:
    """True when the model carries no inertials at all (e.g. a kinematic tree such as the PSM's)."""
    nb = structure.robot.n_bodies
    return nb > 0 and not np.any(np.asarray(structure.prior())[: 10 * nb : 10] > 0)


def _standard(base: BaseParameters, pi_b: np.ndarray, structure: ModelStructure, kind: str) -> np.ndarray:
    if kind == "min_norm":
        return base.min_norm(pi_b)
    if kind == "closest_to_prior":
        return base.closest_to(pi_b, structure.prior())
    raise SolverError(f"unknown standard-parameter choice '{kind}'; use 'closest_to_prior' or 'min_norm'")

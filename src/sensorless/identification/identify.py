"""identify(): robot + logs → physically interpretable dynamic model.

Pipeline: ModelStructure (columns/rows) → streaming compression → base parameters →
solver → standard parameters → IdentificationResult.
"""

from __future__ import annotations

import time
from typing import Callable, Iterable, Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import SolverError
from ..regressor.compress import NormalEquations, compress
from ..regressor.terms import ModelStructure
from ..robot import Robot
from .base import BaseParameters, base_parameters
from .least_squares import solve_least_squares
from .metrics import metrics_from_sums
from .result import IdentificationResult

__all__ = ["identify", "METHODS"]

METHODS = ("ols", "wls")


def identify(
    model: Robot | ModelStructure,
    data: Trajectory | Iterable[Trajectory] | NormalEquations,
    *,
    method: str = "ols",
    weights: str | Sequence[float] | None = None,
    joint_terms: Sequence[str] = ("fv", "fc", "offset", "armature"),
    standard: str = "closest_to_prior",
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
) -> IdentificationResult:
    """Identify base and standard parameters from trajectories (or precompressed equations).

    ``method``: "ols" or "wls" (two-step WLS with per-joint σ unless ``weights`` gives σ).
    ``standard``: how to pick standard parameters from the base ones, "closest_to_prior"
    (nearest to the model's own inertials) or "min_norm".
    """
    if method not in METHODS:
        raise SolverError(f"unknown method '{method}'; choose from {METHODS}")
    structure = model if isinstance(model, ModelStructure) else ModelStructure(model, joint_terms=tuple(joint_terms))
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
    sol = solve_least_squares(ne, base, w)
    params = _standard(base, sol.base_values, structure, standard)
    t_solve = time.perf_counter() - t1
    train = metrics_from_sums(
        structure.row_names, ne.residual_ss(params), ne.c, ne.y_max - ne.y_min, ne.n_samples
    )
    diagnostics = {
        "rank": base.rank,
        "n_standard": structure.n_params,
        "condition_number": sol.condition_number,
        "n_samples": ne.n_samples,
        "residual_sigma": dict(zip(structure.row_names, map(float, sol.sigma))),
        "base_std": np.sqrt(np.maximum(sol.base_covariance_diag, 0)).tolist(),
        "compress_seconds": t_compress,
        "solve_seconds": t_solve,
    }
    settings = {
        "method": method,
        "weights": w.tolist() if isinstance(w, np.ndarray) else w,
        "standard": standard,
        "chunk": chunk,
        **structure.settings(),
    }
    return IdentificationResult(method, structure, base, sol.base_values, params, standard, train, diagnostics, settings)


def _standard(base: BaseParameters, pi_b: np.ndarray, structure: ModelStructure, kind: str) -> np.ndarray:
    if kind == "min_norm":
        return base.min_norm(pi_b)
    if kind == "closest_to_prior":
        return base.closest_to(pi_b, structure.prior())
    raise SolverError(f"unknown standard-parameter choice '{kind}'; use 'closest_to_prior' or 'min_norm'")

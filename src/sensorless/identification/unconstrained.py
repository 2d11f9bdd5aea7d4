"""The LMI program's solution without a conic solve, when no constraint is active.

For γ > 0 and a quadratic regulariser (:class:`~.regularizers.ConstantPullback`,
:class:`~.regularizers.Euclidean`) the objective of :class:`~.lmi.LmiProblem` is the strictly
convex quadratic

    ‖R x − z‖² + (γ/N) ‖G (x − x0)‖²,   GᵀG = blockdiag(FᵀF or I per body, joint_weight · I),

whose unconstrained minimiser is ``x* = (RᵀR + (γ/N) GᵀG)⁻¹ (Rᵀz + (γ/N) GᵀG x0)``. If ``x*``
satisfies every constraint it is the program's unique minimiser (a convex program whose
unconstrained minimiser is feasible), so a conic solve can be skipped: exact, and more accurate
than the interior-point solution in the directions the data barely see. Typical of a strong prior
on a floating base (TALOS: every γ ≥ 3e-5 of the default grid); on arms some constraint
(friction ≥ 0, a body at the boundary of the cone) is usually active and the conic solver runs.
"""

from __future__ import annotations

import numpy as np

from ..parameters import pseudo_inertia, pseudo_inertia_basis
from .constraints import (
    DensityRealizable,
    NonNegativeArmature,
    NonNegativeFriction,
    PseudoInertiaPSD,
    constraint_violation,
)
from .regularizers import ConstantPullback, Euclidean

__all__ = ["regularizer_metric", "satisfies_constraints", "unconstrained_solution"]

_BASIS16 = pseudo_inertia_basis().reshape(10, 16).T


def regularizer_metric(problem) -> np.ndarray | None:
    """``GᵀG`` (p × p) of the problem's regulariser in scaled coordinates, None if not quadratic."""
    reg = problem.regularizer
    return reg.metric(problem.ctx) if type(reg) in (ConstantPullback, Euclidean) else None


def satisfies_constraints(problem, x: np.ndarray) -> bool:
    """Whether the scaled point ``x`` satisfies every constraint of ``problem`` (the default
    builders checked numerically, any other through :func:`~.constraints.constraint_violation`)."""
    ctx = problem.ctx
    for b in problem.builders:
        if isinstance(b, PseudoInertiaPSD):
            J = pseudo_inertia(x[: ctx.structure.n_body_params].reshape(-1, 10))
            if np.linalg.eigvalsh(J)[:, 0].min() < b.eps:
                return False
        elif isinstance(b, DensityRealizable):
            if any((_BASIS16.T @ ctx.scaled_Q(k).ravel()) @ x[ctx.body_slice(k)] < 0 for k, _ in ctx.bounded_bodies()):
                return False
        elif isinstance(b, (NonNegativeFriction, NonNegativeArmature)):
            idx = np.concatenate([ctx.term_indices(t) for t in b.terms] or [np.zeros(0, dtype=int)])
            if idx.size and x[idx].min() < 0:
                return False
        elif constraint_violation(b, ctx.params(x), ctx) > 0:
            return False
    return True


def unconstrained_solution(problem, gamma: float, metric: np.ndarray | None = None) -> np.ndarray | None:
    """Standard parameters of the program's solution at ``gamma`` when the unconstrained minimiser
    is feasible (module docstring); None when γ = 0, the regulariser is not quadratic, or a
    constraint would be violated (then the conic solver decides). ``metric``: the problem's
    :func:`regularizer_metric`, if already computed. Not thread-safe for builders other than the
    defaults (cvxpy expressions are built)."""
    if not gamma > 0:
        return None
    M = regularizer_metric(problem) if metric is None else metric
    if M is None:
        return None
    R, z = problem.data_factor
    lam = float(gamma) / problem.n_samples
    H = R.T @ R + lam * M
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    rhs = R.T @ z + lam * (M @ problem.ctx.x0)
    x = np.linalg.solve(L.T, np.linalg.solve(L, rhs))
    if not np.all(np.isfinite(x)) or not satisfies_constraints(problem, x):
        return None
    return problem.ctx.params(x)

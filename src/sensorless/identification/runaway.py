"""Regularisation that cannot run away: a floor on the cross-validated γ, and the active bounds.

The standard parameters of an arm always have directions no joint-torque log sees (the
base-parameter regrouping), and a log that moves one joint at a time leaves base directions
unexcited too. With γ = 0 the LMI leaves those directions to the solver, bounded only by the
physical-consistency constraints: bodies of hundreds of kg. :func:`gamma_guard` therefore refuses
a cross-validated γ below a floor when the problem has such directions (a CV winner γ = 0 always,
any winner below the floor when base directions are unexcited):

    γ_floor = ρ / τ²,   ρ = Σ_r w_r RSS_r / Σ_r w_r c_r  (the unconstrained fit's relative residual),

the MAP weight of a prior trusted to within its own size (τ = :data:`PRIOR_TRUST` = 1; see
:mod:`.lmi`: γ ≈ ρ/τ²), never below :data:`GAMMA_FLOOR_MIN`. The γ used, the CV winner, the
floor and why it applied go to ``diagnostics["gamma_guard"]``.
"""

from __future__ import annotations

import numpy as np

from ..errors import setting
from ..parameters import pseudo_inertia
from ..regressor.normal_equations import NormalEquations
from ..regressor.joint_terms import terms_where
from .least_squares import MIN_SINGULAR_RATIO, solve_truncated_svd

__all__ = ["GAMMA_FLOOR_MIN", "PRIOR_TRUST", "active_bounds", "gamma_floor", "gamma_guard"]

PRIOR_TRUST = 1.0  # τ: relative uncertainty of the prior pseudo-inertias behind the floor
GAMMA_FLOOR_MIN = 1e-8  # the smallest positive γ of the default grid
ACTIVE_MARGIN = 1e-3  # density margin below which an ellipsoid counts as active
PSD_ACTIVE = 1e-6  # λ_min(Ĵ)/λ_max(Ĵ) below which a body is on the boundary of the cone (degenerate)


def gamma_floor(ne: NormalEquations, row_weights=None) -> tuple[float, float]:
    """``(γ_floor, ρ)`` (module docstring)."""
    w = np.ones(ne.A.shape[0]) if row_weights is None else np.asarray(row_weights, dtype=float)
    free, _ = solve_truncated_svd(ne, rcond=MIN_SINGULAR_RATIO, row_weights=row_weights)
    rho = float(w @ ne.residual_ss(free)) / max(float(w @ ne.c), 1e-300)
    return max(rho / PRIOR_TRUST**2, GAMMA_FLOOR_MIN), rho


def gamma_guard(ne: NormalEquations, row_weights, gamma_cv: float, report: dict | None, regularization) -> dict:
    """The γ to use after cross-validation chose ``gamma_cv`` (module docstring)."""
    unexcited = bool(report and report.get("not_excited"))
    floor, rho = gamma_floor(ne, row_weights)
    why = None
    if regularization is not None:
        if gamma_cv == 0:
            why = "γ = 0 leaves the directions no log can see (individual body masses among them) to the solver"
        elif unexcited and gamma_cv < floor:
            why = "base-parameter directions are not excited by this log"
    out = {"gamma_cv": float(gamma_cv), "floor": floor, "relative_residual": rho, "prior_trust": PRIOR_TRUST,
           "unexcited_base_directions": len(report["not_excited"]) if unexcited else 0,
           "applied": why is not None, "gamma": floor if why else float(gamma_cv)}
    if why:
        out["reason"] = why
        out["message"] = (f"cross-validation chose γ = {gamma_cv:g} but {why}: γ raised to the floor {floor:.3g} "
                          f"(the relative residual ρ = {rho:.3g}: a prior trusted to its own size); "
                          f"give {setting('gamma')} to override")
    return out


def active_bounds(lmi: dict, params: np.ndarray, structure) -> dict:
    """Bounds of the LMI solution that are active: per body "density ellipsoid" (margin <
    :data:`ACTIVE_MARGIN`) and "pseudo-inertia ⪰ 0" (a degenerate body: λ_min(J)/λ_max(J) <
    :data:`PSD_ACTIVE` in the solver's scaled units); joint terms held at 0 by "≥ 0"."""
    bodies: dict[str, list[str]] = {}
    s = lmi.get("settings", {})
    m = np.asarray(s.get("body_mass_scale", []), dtype=float)
    ell = np.asarray(s.get("body_length_scale", []), dtype=float)
    for k, rep in enumerate(lmi.get("bodies", [])):
        hits = []
        margin = rep.get("ellipsoid_margin")
        if margin is not None and np.isfinite(margin) and margin < ACTIVE_MARGIN:
            hits.append("density ellipsoid")
        if k < len(m):
            sc = np.array([m[k]] + [m[k] * ell[k]] * 3 + [m[k] * ell[k] ** 2] * 6)
            lam = np.linalg.eigvalsh(pseudo_inertia(params[10 * k: 10 * k + 10] / sc))
            if lam[0] < PSD_ACTIVE * max(abs(lam[-1]), 1e-300):
                hits.append("pseudo-inertia ⪰ 0")
        if hits:
            bodies[rep.get("name", str(k))] = hits
    joints = []
    for j in structure.robot.term_joints:
        for t in terms_where("nonnegative"):
            if t in structure.terms_of(j) and params[structure.joint_term_index(j, t)] <= 0.0:
                joints.append(f"{j}.{t}")
    return {"bodies": bodies, "joint_terms_at_zero": joints}

"""Physically consistent identification: a convex (LMI) program on compressed data.

    minimise_π   N ‖W π − y‖²_w / ‖y‖²_w  +  γ · R(π; π0)
    subject to   J_k(π) ⪰ 0,  tr(J_k Q_k) ≥ 0   (every body; see .constraints)
                 fv, fc, armature ≥ 0           (+ optional mass bounds)

* **Data term.** Only the compressed normal equations are used,
  ``‖W π − y‖²_w = πᵀAπ − 2bᵀπ + c`` with ``(A, b, c) = ne.total(row_weights)``, so the
  program's size does not depend on the number of samples. It is measured in units of
  the mean squared torque of one sample, ``‖y‖²_w / N`` (N samples), i.e. ``N`` times the
  *relative residual* ``‖W π − y‖²_w / ‖y‖²_w`` (1: explains nothing; reported as
  ``LmiSolution.relative_residual``).
  ``A`` is rank deficient (only base parameters are identifiable): after scaling, ``A/c``
  is reduced to its identifiable directions (through ``B`` of :func:`base_parameters`
  when ``base`` is given, else directly), Jacobi-equilibrated and eigendecomposed,
  ``A/c = Σ_i λ_i v_i v_iᵀ`` keeping ``λ_i > rank_tol · λ_max``; the data term is then
  ``‖R x − z‖² + const`` with ``R = Λ^{1/2} Vᵀ`` (``rank × p``, so cvxpy sees a small
  convex quadratic). The regulariser fixes the directions the data cannot see.
* **γ** weighs the (dimensionless) regulariser against that data term. Read as a
  Gaussian prior (MAP): ``γ ≈ ρ / τ²`` with ``ρ`` the relative noise power
  (σ²/mean y²; 3 % noise → ρ ≈ 1e-3) and ``τ`` the relative uncertainty of the prior
  pseudo-inertias; the default ``γ = 1e-3`` is a weak prior (τ ≈ 1 at 3 % noise) that
  mostly fixes what the data cannot see. Because the data term grows with N, a fixed γ
  lets more data override the prior. Pick it by held-out residual
  (:func:`select_gamma`, :func:`cross_validate_gamma`). Internally the solver minimises
  ``relative residual + (γ/N) R`` (same minimiser, O(1) numbers).
* **Scaling.** The variable is ``x`` with ``π = scale ⊙ x``: bodies by prior mass and
  radius of gyration (a congruence of ``J``, see :mod:`.constraints`), joint terms by
  ``√(c / A_jj)`` (a unit step of one joint term changes the normalised data term by O(1)).
  The conic solver sees O(1) numbers, so a 33-body humanoid solves as easily as an arm.
* **Solvers.** MOSEK first if it is installed *and* licensed (checked once with a tiny
  solve), then Clarabel, then SCS. An inaccurate status moves on to the next solver;
  infeasibility raises :class:`SolverError` naming the constraints the prior violates.
* **Two routes to the solver.** With a quadratic regulariser (pullback, Euclidean, none) and
  constraints that give conic rows (every builder of :mod:`.constraints`), Clarabel gets the
  program directly as ``min ½ xᵀPx + qᵀx, A x + s = b, s ∈ K`` with
  ``P = 2 (RᵀR + (γ/N) G)``, ``q = −2 (Rᵀz + (γ/N) G x0)`` (``G`` the regulariser's metric)
  and one cone block per constraint (``LmiSolution.settings["route"] = "clarabel"``): p
  variables, no cvxpy import (~0.55 s) and no compilation (~4 ms a solve). MOSEK, SCS, the
  entropic regulariser and user-written builders go through cvxpy (``"cvxpy"``), the same
  program written as cvxpy expressions (tested to give the same solutions).
* **Consistency.** After the solve each body is checked (``λ_min(J_k) ≥ −1e-8 ‖J_k‖``);
  a body slightly outside the cone because of solver tolerance is projected onto it
  (eigenvalues of ``Ĵ_k`` clipped at ``ε``) and listed in ``LmiSolution.projected``.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import DataError, ExcitationError, SolverError, python_only, setting
from ..parameters import (
    ConsistencyReport,
    check_physical_consistency,
    from_pseudo_inertia,
    pseudo_inertia,
)
from ..regressor.normal_equations import NormalEquations
from ..regressor.terms import ModelStructure
from .base import BaseParameters
from .constraints import (
    ConstraintBuilder,
    LmiContext,
    constraint_violation,
    default_constraints,
)
from .ellipsoids import BoundingEllipsoid, resolve_ellipsoids
from .regularizers import Regularizer, make_regularizer

__all__ = [
    "CONSISTENCY_TOL",
    "DEFAULT_GAMMAS",
    "BodyReport",
    "LmiProblem",
    "LmiSolution",
    "available_solvers",
    "body_reports",
    "build_lmi",
    "mosek_available",
    "solve_lmi",
]

CONSISTENCY_TOL = 1e-8  # λ_min(J_k) ≥ −tol · ‖J_k‖₂ counts as consistent
# 0 (no prior: the data alone, inside the constraints), then 1e-8 … 10 in half decades
DEFAULT_GAMMAS: tuple[float, ...] = (0.0,) + tuple(float(g) for g in np.logspace(-8, 1, 19))
# statuses as cvxpy names them (the Clarabel route reports the same words)
OPTIMAL, OPTIMAL_INACCURATE = "optimal", "optimal_inaccurate"
INFEASIBLE, INFEASIBLE_INACCURATE = "infeasible", "infeasible_inaccurate"
_CLARABEL_STATUS = {  # as cvxpy's Clarabel interface maps them
    "Solved": OPTIMAL, "AlmostSolved": OPTIMAL_INACCURATE, "PrimalInfeasible": INFEASIBLE,
    "AlmostPrimalInfeasible": INFEASIBLE_INACCURATE, "DualInfeasible": "unbounded",
    "AlmostDualInfeasible": "unbounded_inaccurate", "MaxIterations": "user_limit", "MaxTime": "user_limit",
}
# cvxpy's compilation is not thread-safe (a global id counter): the first solve of a program for a
# solver, which compiles it, holds this lock; re-solves with new parameter values only fill in data
_COMPILE_LOCK = threading.Lock()
_SOLVER_OPTIONS: dict[str, dict[str, Any]] = {
    "CLARABEL": {},
    "SCS": {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iters": 20_000},
    "MOSEK": {},
}


@functools.cache
def mosek_available() -> bool:
    """True only if ``import mosek`` works, cvxpy lists MOSEK and a tiny solve succeeds."""
    try:
        import mosek  # noqa: F401
    except ImportError:
        return False
    import cvxpy as cp

    if "MOSEK" not in cp.installed_solvers():
        return False
    try:
        t = cp.Variable()
        prob = cp.Problem(cp.Minimize(t), [t >= 1])
        prob.solve(solver="MOSEK")
        return prob.status == cp.OPTIMAL
    except Exception:  # noqa: BLE001 - no licence, broken install: MOSEK is simply not used
        return False


def available_solvers() -> list[str]:
    """Solvers tried by default, in order (found without importing them or cvxpy)."""
    return list(_available_solvers())


@functools.cache
def _available_solvers() -> tuple[str, ...]:
    out = ("MOSEK",) if mosek_available() else ()
    return out + tuple(name for name in ("CLARABEL", "SCS") if importlib.util.find_spec(name.lower()) is not None)


@dataclass
class BodyReport(ConsistencyReport):
    """:class:`ConsistencyReport` plus the density margin ``tr(J Q)/m`` in the body's
    ellipsoid (nan without one), whether the body was projected onto the cone after the
    solve and by how much (``−λ_min(Ĵ)/‖Ĵ‖₂`` before the projection, 0 if not projected)."""

    ellipsoid_margin: float = float("nan")
    projected: bool = False
    projection: float = 0.0

    def to_dict(self) -> dict:
        d = asdict(self)
        d["com"] = self.com.tolist()
        d["principal_moments"] = self.principal_moments.tolist()
        return d


@dataclass
class LmiSolution:
    """Outcome of :func:`solve_lmi`. ``params`` are standard parameters (``structure.labels``).

    ``objective = N · relative_residual + γ · regularization_term`` with
    ``relative_residual = ‖W π − y‖²_w / ‖y‖²_w`` on the training data (N samples).
    """

    params: np.ndarray
    status: str
    solver: str
    objective: float
    relative_residual: float
    regularization_term: float
    setup_seconds: float
    solve_seconds: float
    consistency: list[BodyReport]
    projected: list[str] = field(default_factory=list)
    attempts: list[tuple[str, str]] = field(default_factory=list)
    settings: dict = field(default_factory=dict)

    @property
    def consistent(self) -> bool:
        return all(r.consistent for r in self.consistency)

    def summary(self) -> dict:
        scalars = ("status", "solver", "objective", "relative_residual", "regularization_term", "setup_seconds",
                   "solve_seconds", "consistent", "projected")
        return {**{k: getattr(self, k) for k in scalars}, "attempts": [list(a) for a in self.attempts],
                "bodies": [r.to_dict() for r in self.consistency], "settings": self.settings}


def _data_factor(
    A: np.ndarray, b: np.ndarray, c: float, scale: np.ndarray, base: BaseParameters | None, rank_tol: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """``R, z, e0`` with ``(xᵀ Â x − 2 b̂ᵀx + 1) = ‖R x − z‖² + e0`` for ``π = scale ⊙ x``, ``Â = A/c``."""
    if base is None:  # reduced coordinates y = x
        Mp = np.eye(len(scale))
        M, m = scale[:, None] * A * scale[None, :] / c, scale * b / c
    else:  # reduced coordinates y = π_b = B π = B (scale ⊙ x)
        ind = base.independent
        Mp = base.B * scale[None, :]
        M, m = A[np.ix_(ind, ind)] / c, b[ind] / c
    diag = np.diag(M).copy()
    dead = diag <= 1e-14 * max(diag.max(), 1e-300)  # structurally unexcited columns (round-off only)
    M, m = M.copy(), m.copy()
    M[dead, :] = M[:, dead] = 0.0
    m[dead] = 0.0
    d = np.sqrt(np.where(dead, 1.0, diag))
    lam, V = np.linalg.eigh(M / np.outer(d, d))
    keep = lam > rank_tol * max(lam[-1], 1e-300)
    if lam[-1] <= 0 or not np.any(keep):
        raise ExcitationError("the data do not excite any parameter (the regressor is zero on every sample)")
    lam, V = lam[keep], V[:, keep]
    R = (np.sqrt(lam)[:, None] * (V.T * d[None, :])) @ Mp
    z = (V.T @ (m / d)) / np.sqrt(lam)
    return R, z, float(1.0 - z @ z)


class LmiProblem:
    """The program for one training set; :meth:`solve` for any γ. On the Clarabel route only ``P``
    and ``q`` depend on γ; on the cvxpy route γ is a cvxpy Parameter, so re-solving skips
    compilation (the cvxpy program is built on first use: :attr:`problem`). Build with
    :func:`build_lmi`."""

    def __init__(
        self,
        ne: NormalEquations,
        structure: ModelStructure,
        *,
        base: BaseParameters | None = None,
        prior: np.ndarray | None = None,
        regularization: str | Regularizer | None = "pullback",
        constraints: Sequence[ConstraintBuilder] | None = None,
        ellipsoids: Mapping[str, Any] | bool | str | None = None,
        row_weights: np.ndarray | None = None,
        eps: float = 0.0,
        rank_tol: float = 1e-12,
    ) -> None:
        t0 = time.perf_counter()
        self.structure = structure
        p = structure.n_params
        if ne.A.shape[1] != p:
            raise DataError(f"normal equations have {ne.A.shape[1]} parameters, the structure {p}")
        A, b, c = ne.total(None if row_weights is None else np.asarray(row_weights, dtype=float))
        if not c > 0:
            raise DataError("every measured torque is zero (‖y‖² = 0): nothing to identify")
        prior = structure.prior() if prior is None else np.asarray(prior, dtype=float)
        ell = resolve_ellipsoids(structure.robot, ellipsoids, prior=prior)
        nb = structure.n_body_params
        dA = np.diag(A)[nb:]
        excited = dA > 1e-14 * c
        js = np.where(excited, np.sqrt(c / np.where(excited, dA, 1.0)), 1.0)
        self.ctx = ctx = LmiContext.create(structure, prior, ell, js)
        self.builders = list(default_constraints(eps, density=bool(ell)) if constraints is None else constraints)
        self.regularizer = make_regularizer(regularization)
        R, z, self.e0 = _data_factor(A, b, c, ctx.scale, base, rank_tol)
        self.data_factor = (R, z)  # data term ‖R x − z‖² (+ e0)
        self.n_samples = max(int(ne.n_samples), 1)
        self.rank = R.shape[0]
        self.eps = eps
        self._conic = self._conic_program()
        self._cvx: dict[str, Any] | None = None
        self.settings = {
            "regularization": getattr(self.regularizer, "name", None),
            "constraints": [bld.name for bld in self.builders],
            "eps": eps,
            "row_weights": None if row_weights is None else np.asarray(row_weights, dtype=float).tolist(),
            "data_rank": self.rank,
            "rank_tol": rank_tol,
            "reduced_by": "base_parameters" if base is not None else "eigendecomposition",
            "ellipsoids": {k: e.to_dict() for k, e in ell.items()},
            "body_mass_scale": ctx.body_mass.tolist(),
            "body_length_scale": ctx.body_length.tolist(),
        }
        self.build_seconds = time.perf_counter() - t0
        self._first_solve = True
        self._compiled: set[str] = set()  # solvers the cvxpy program was compiled for

    # ---- the two routes ----------------------------------------------------------------
    def _conic_program(self) -> dict[str, Any] | None:
        """Clarabel's data but ``P, q`` (which depend on γ), or None when the regulariser is not
        quadratic or a builder gives no conic rows (then only the cvxpy route solves)."""
        reg = self.regularizer
        if (reg is not None and not hasattr(reg, "metric")) or not all(hasattr(b, "conic") for b in self.builders):
            return None
        rows = [r for b in self.builders for r in b.conic(self.ctx)]
        order = {"zero": 0, "nonneg": 1, "soc": 2, "psd": 3}
        rows.sort(key=lambda r: order[r.kind])  # stable: the builders' order within a kind
        p = self.structure.n_params
        R, z = self.data_factor
        G = reg.metric(self.ctx) if reg is not None else np.zeros((p, p))
        return {
            "rows": rows,
            "A": np.concatenate([r.A for r in rows]) if rows else np.zeros((0, p)),
            "b": np.concatenate([r.b for r in rows]) if rows else np.zeros(0),
            "RtR": R.T @ R, "Rtz": R.T @ z, "G": G, "Gx0": G @ self.ctx.x0,
        }

    def quadratic_objective(self, gamma: float) -> tuple[np.ndarray, np.ndarray]:
        """``P, q`` with ``½ xᵀPx + qᵀx + ‖z‖² + (γ/N) x0ᵀG x0`` = the solver's objective
        ``‖R x − z‖² + (γ/N)(x − x0)ᵀG(x − x0)`` (Clarabel route only)."""
        d = self._conic
        lam = float(gamma) / self.n_samples
        return 2.0 * (d["RtR"] + lam * d["G"]), -2.0 * (d["Rtz"] + lam * d["Gx0"])

    def _solve_clarabel(self, gamma: float, verbose: bool) -> tuple[str, np.ndarray | None]:
        """One direct Clarabel solve (module docstring); ``(status, x)`` with cvxpy's status words.
        Reads the problem's data only, so the folds' problems can be solved in threads."""
        import clarabel
        import scipy.sparse as sp

        d = self._conic
        P, q = self.quadratic_objective(gamma)
        if not (np.isfinite(P).all() and np.isfinite(q).all()):  # Clarabel would panic, not raise
            return "error: non-finite data", None
        A = sp.csc_matrix(d["A"])
        A.eliminate_zeros()  # Clarabel keeps stored zeros in its KKT pattern
        kinds = {"zero": clarabel.ZeroConeT, "nonneg": clarabel.NonnegativeConeT,
                 "soc": clarabel.SecondOrderConeT, "psd": clarabel.PSDTriangleConeT}
        cones = [kinds[r.kind](r.dim if r.kind in ("soc", "psd") else len(r.b)) for r in d["rows"]]
        settings = clarabel.DefaultSettings()
        settings.verbose = verbose
        for key, value in _SOLVER_OPTIONS["CLARABEL"].items():  # the options the cvxpy route passes
            setattr(settings, key, value)
        try:
            sol = clarabel.DefaultSolver(sp.csc_matrix(np.triu(P)), q, A, d["b"], cones, settings).solve()
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            return f"error: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", None
        status = _CLARABEL_STATUS.get(str(sol.status), "solver_error")
        x = np.asarray(sol.x, dtype=float) if sol.x is not None else None
        return status, (x if x is not None and x.shape == (len(q),) and np.isfinite(x).all() else None)

    def _cvxpy_program(self) -> dict[str, Any]:
        """The same program as cvxpy expressions (built on first use)."""
        if self._cvx is None:
            import cvxpy as cp

            R, z = self.data_factor
            x = cp.Variable(self.structure.n_params, name="x")
            gamma = cp.Parameter(nonneg=True, name="gamma_over_n", value=1e-3 / self.n_samples)
            data_expr = cp.sum_squares(R @ x - z)
            reg_expr = self.regularizer(x, self.ctx) if self.regularizer is not None else None
            obj = data_expr if reg_expr is None else data_expr + gamma * reg_expr
            cons = [con for bld in self.builders for con in bld(x, self.ctx)]
            self._cvx = {"x": x, "gamma": gamma, "data_expr": data_expr, "reg_expr": reg_expr,
                         "problem": cp.Problem(cp.Minimize(obj), cons)}
        return self._cvx

    # the cvxpy program's parts (tests and callers that write their own solves use them)
    problem = property(lambda self: self._cvxpy_program()["problem"])
    x = property(lambda self: self._cvxpy_program()["x"])
    gamma = property(lambda self: self._cvxpy_program()["gamma"])
    data_expr = property(lambda self: self._cvxpy_program()["data_expr"])
    reg_expr = property(lambda self: self._cvxpy_program()["reg_expr"])

    def _solve_cvxpy(self, name: str, gamma: float, verbose: bool) -> tuple[str, np.ndarray | None, float]:
        """``(status, x, compilation seconds)`` from cvxpy with solver ``name``."""
        import cvxpy as cp

        cvx = self._cvxpy_program()
        cvx["gamma"].value = float(gamma) / self.n_samples
        prob = cvx["problem"]
        t0 = time.perf_counter()
        try:
            with _COMPILE_LOCK if name not in self._compiled else contextlib.nullcontext():
                prob.solve(solver=name, verbose=verbose, **_SOLVER_OPTIONS.get(name, {}))
                self._compiled.add(name)
        except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
            return f"error: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", None, 0.0
        comp = min(float(prob.compilation_time or 0.0), time.perf_counter() - t0)
        x = cvx["x"].value
        return prob.status, (None if x is None else np.array(x, dtype=float)), comp

    # ---- solving ---------------------------------------------------------------------
    def solve(
        self, gamma: float = 1e-3, *, solver: str | None = None, accept_inaccurate: bool = False, verbose: bool = False
    ) -> LmiSolution:
        """Solve for one γ. ``solver=None`` tries :func:`available_solvers` in order;
        a name (e.g. "SCS") uses only that solver. If every solver ends "optimal_inaccurate"
        (reduced accuracy), the first such solution is returned when ``accept_inaccurate``,
        else :class:`SolverError` is raised."""
        if gamma < 0:
            raise SolverError(f"gamma must be >= 0, got {gamma}")
        order = available_solvers() if solver is None else [solver.upper()]
        attempts: list[tuple[str, str]] = []
        t_setup = self.build_seconds if self._first_solve else 0.0  # build (+ cvxpy's compilation)
        self._first_solve = False
        t_solve = 0.0
        fallback: tuple[str, np.ndarray, str] | None = None
        for name in order:
            t0 = time.perf_counter()
            route, comp = ("clarabel", 0.0) if name == "CLARABEL" and self._conic is not None else ("cvxpy", 0.0)
            if route == "clarabel":
                status, x = self._solve_clarabel(gamma, verbose)
            else:
                status, x, comp = self._solve_cvxpy(name, gamma, verbose)
            wall = time.perf_counter() - t0
            t_setup += comp
            t_solve += wall - comp
            attempts.append((name, status))
            if status == OPTIMAL and x is not None:
                return self._solution(name, status, gamma, t_setup, t_solve, attempts, x, route)
            if status == INFEASIBLE:
                raise SolverError(self._infeasible_message(name))
            if status == OPTIMAL_INACCURATE and fallback is None and x is not None:
                fallback = (name, x, route)
        if fallback is not None and accept_inaccurate:
            return self._solution(fallback[0], OPTIMAL_INACCURATE, gamma, t_setup, t_solve, attempts, fallback[1],
                                  fallback[2])
        if attempts and all(s == INFEASIBLE_INACCURATE for _, s in attempts):
            raise SolverError(self._infeasible_message("/".join(order)))
        tried = ", ".join(f"{n}: {s}" for n, s in attempts)
        raise SolverError(
            f"the physically consistent solve did not converge ({tried}). Try a larger {setting('gamma')} "
            f"(now {gamma:g}), {setting('regularization', 'pullback')}, row weights that bring joints to similar "
            f"torque scales ({setting('weights')}), fewer joint terms ({setting('joint_terms')}), or install MOSEK"
            + python_only("accept_inaccurate=True keeps the inaccurate solution")
        )

    def _infeasible_message(self, solver: str) -> str:
        prior = self.ctx.prior
        bad = []
        for bld in self.builders:
            v = constraint_violation(bld, prior, self.ctx)
            if v > 1e-9:
                bad.append(f"{bld.name} (prior violates it by {v:.3g}; {bld.hint})")
        if bad:
            return f"{solver}: the constraints are infeasible. Relax: " + "; ".join(bad)
        hints = "; ".join(f"{b.name}: {b.hint}" for b in self.builders)
        return (
            f"{solver} reports infeasibility although the prior satisfies every constraint: a numerical "
            "failure. Try another solver" + python_only("solver='SCS' or 'CLARABEL'") + f", or relax: {hints}"
        )

    def _regularization_value(self, x: np.ndarray) -> float:
        if self.regularizer is None:
            return 0.0
        if self._conic is not None:
            d = x - self.ctx.x0
            return float(d @ self._conic["G"] @ d)
        cvx = self._cvxpy_program()
        cvx["x"].value = x
        return float(cvx["reg_expr"].value)

    def _solution(self, solver: str, status: str, gamma: float, t_setup: float, t_solve: float, attempts,
                  x: np.ndarray | None = None, route: str = "cvxpy") -> LmiSolution:
        """The solution at scaled ``x`` (default: the cvxpy variable's value), bodies projected
        onto the cone where the solver left them slightly outside."""
        ctx = self.ctx
        x = np.array(self.x.value if x is None else x, dtype=float)
        params = ctx.params(x)
        R, z = self.data_factor
        rel = max(float(np.sum((R @ x - z) ** 2)) + self.e0, 0.0)
        reg = self._regularization_value(x)
        projected: dict[str, float] = {}
        names = ctx.body_names
        for k in range(ctx.n_bodies):
            Jh = pseudo_inertia(x[ctx.body_slice(k)])
            lam, V = np.linalg.eigh(Jh)
            if lam[0] < self.eps:
                Jh = (V * np.maximum(lam, self.eps)) @ V.T
                params[ctx.body_slice(k)] = ctx.scale[ctx.body_slice(k)] * from_pseudo_inertia(Jh)
                projected[names[k]] = float((self.eps - lam[0]) / max(np.abs(lam).max(), 1e-300))
        reports = body_reports(params[: ctx.structure.n_body_params], names, ctx.ellipsoids, projected)
        settings = {**self.settings, "gamma": float(gamma), "solver": solver, "route": route,
                    **self.structure.settings()}
        return LmiSolution(
            params, status, solver, self.n_samples * rel + gamma * reg, rel, reg, t_setup, t_solve, reports,
            list(projected), attempts, settings,
        )


def body_reports(
    pi: np.ndarray,
    names: Sequence[str],
    ellipsoids: Mapping[str, BoundingEllipsoid] | None = None,
    projected: Mapping[str, float] | None = None,
    tol: float = CONSISTENCY_TOL,
) -> list[BodyReport]:
    """Per-body consistency (``λ_min(J) ≥ −tol ‖J‖₂``), triangle margins and ellipsoid margins;
    ``projected`` maps projected bodies to the size of their projection."""
    ellipsoids = ellipsoids or {}
    projected = projected or {}
    P = np.asarray(pi, dtype=float).reshape(-1, 10)
    lam = np.linalg.eigvalsh(pseudo_inertia(P))
    out = []
    for k, r in enumerate(check_physical_consistency(P, names)):
        E = ellipsoids.get(r.name)
        ok = bool(lam[k, 0] >= -tol * np.abs(lam[k]).max())
        margin = E.density_margin(P[k]) if E is not None else float("nan")
        out.append(
            BodyReport(
                **{**vars(r), "consistent": ok},
                ellipsoid_margin=margin,
                projected=r.name in projected,
                projection=float(projected.get(r.name, 0.0)),
            )
        )
    return out


def build_lmi(ne: NormalEquations, structure: ModelStructure, **kwargs: Any) -> LmiProblem:
    """:class:`LmiProblem` for the training equations ``ne`` (keywords as :func:`solve_lmi`)."""
    return LmiProblem(ne, structure, **kwargs)


def solve_lmi(
    ne: NormalEquations,
    structure: ModelStructure,
    *,
    base: BaseParameters | None = None,
    prior: np.ndarray | None = None,
    regularization: str | Regularizer | None = "pullback",
    gamma: float = 1e-3,
    constraints: Sequence[ConstraintBuilder] | None = None,
    ellipsoids: Mapping[str, Any] | bool | str | None = None,
    row_weights: np.ndarray | None = None,
    solver: str | None = None,
    eps: float = 0.0,
    rank_tol: float = 1e-12,
    accept_inaccurate: bool = False,
    verbose: bool = False,
) -> LmiSolution:
    """Physically consistent parameters from compressed normal equations (module docstring).

    ``prior`` defaults to ``structure.prior()`` (model inertials, zero friction, model
    armature). ``regularization``: "pullback" (default), "entropic", "euclidean", a
    regulariser instance or None. ``constraints`` defaults to
    :func:`~.constraints.default_constraints` (``J ⪰ eps``, density in the ellipsoids,
    friction and armature ≥ 0). ``ellipsoids``: None (automatic, see
    :func:`~.ellipsoids.resolve_ellipsoids`), "kinematic", False (none) or
    ``{body: (center, semi_axes, rotation)}``. ``row_weights`` are per-row weights w_r
    (= 1/σ_r²). ``eps`` (≥ 0) is the margin of ``Ĵ_k ⪰ eps I`` in the body's scaled units
    (default constraints and the final projection). ``base`` reduces the data term through
    the base-parameter map instead of an eigendecomposition (same solution). Raises
    :class:`SolverError` when infeasible or not solved accurately (``accept_inaccurate``
    returns a reduced-accuracy solution instead).
    """
    prob = LmiProblem(
        ne, structure, base=base, prior=prior, regularization=regularization, constraints=constraints,
        ellipsoids=ellipsoids, row_weights=row_weights, eps=eps, rank_tol=rank_tol,
    )
    return prob.solve(gamma, solver=solver, accept_inaccurate=accept_inaccurate, verbose=verbose)

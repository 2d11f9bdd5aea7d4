"""The one model every output presents: physically consistent, closest to the prior, explaining the data.

A fit's estimate matches the data exactly along every direction the log sees, however weakly: on a
weak log (one joint moving at a time, a short sweep) most of those directions are noise, and a body
whose mass only enters them can come out 2–18× its CAD mass. What ``result.json``, the console,
``report.html`` and ``model.urdf`` show is instead the solution of ::

    min_π  Σ_k ½ tr((J0_k⁻¹ (J_k − J0_k))²)                  the prior's metric (:func:`.regularizers.pullback_matrix`)
    s.t.   (π − π*)ᵀ A (π − π*) ≤ RSS(π̂) − RSS(π*) + s² · REGION
           J_k(π) ⪰ 0                                         every body physical
           the fit's sign constraints on the joint terms (the registry's ``nonnegative`` flag)

then (step 2) the prior's mass ``m_k = m0_k`` for each body whose mass the data do not determine
(verdict ≠ ``data``), moving the inertials only along the structural null space ``B Δ = 0`` of the base
parameters (no motion's torques change; :func:`.urdf_values.reach_prior_masses`). In step 1, ``A`` is the
fit's weighted normal matrix, ``π*`` its unconstrained least-squares minimiser,
``π̂`` the fit and ``s²`` the weighted residual variance; its region holds the models that explain the
data as well as the fit up to :data:`REGION` = 0.1 s² of residual: along any direction the data determine,
a move of at most √0.1 ≈ 0.3 of its (linear, so lower-bound) σ. A direction the data do not determine
costs almost nothing there and goes to the prior; the presented model predicts as the fit does (UR5 peer
hard case held-out 0.258 % against the fit's 0.257 %; a region of 1 s² gave 0.269 %, one of χ²_{0.95}(rank)
let a 69-parameter Panda fit drift to 1.2× its held-out RMSE). The region uses the linear σ, not the resampled
one, so that the same equations give the same model whichever path compressed them (streamed, in memory,
precompressed). A fit that is no physical body (least squares) may lie far from every physical model
that explains the data; its region is the likelihood-ratio 95 % region instead,
``(π − π*)ᵀ A (π − π*) ≤ s² χ²_{0.95}(rank)``, the one that holds the truth (a 1σ region around an OLS
fit on a Panda log left only a 40 kg link). Fixing the masses inside the data's region instead would move directions the log barely sees but
another motion does (KUKA, trained on one excitation, predicting another: 13.6 → 14.5 % NRMSE). Where a
prior mass leaves no physical body, that body keeps the step-1 mass (greedily, farthest from the prior
first, :func:`.urdf_values.greedy_prefixes`) and its verdict says so. Step 1 is assembled for Clarabel's own
API (no cvxpy import: ``--method ols`` never loads it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["REGION", "presented_parameters"]

REGION = 0.1  #: the RSS the presented model may add to the fit's, in units of s²
_TIE = 1e-8  # pull of the joint terms toward the fit's values (scaled units)


def _body_factor(pi0: np.ndarray) -> np.ndarray:
    """``F`` (10×10) with ``‖F Δπ‖² = ½ tr((J0⁻¹ ΔJ)²)``, J0 the prior body's pseudo-inertia floored at 1e-6 of its largest eigenvalue."""
    from ..parameters import pseudo_inertia
    from .regularizers import eigenvalue_floor, pullback_matrix

    J0 = pseudo_inertia(pi0)
    top = max(float(np.linalg.eigvalsh(0.5 * (J0 + J0.T)).max()), 1e-12)
    M = pullback_matrix(eigenvalue_floor(J0, 1e-6 * top))
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    return (V * np.sqrt(np.maximum(lam, 0.0))).T


def presented_parameters(structure, ne, fit: np.ndarray, prior: np.ndarray, verdicts: dict, B: np.ndarray,
                         row_weights=None, nonnegative: np.ndarray | None = None) -> tuple[np.ndarray | None, dict]:
    """``(π, info)`` of the two steps above, or ``(None, info)`` with ``info["reason"]`` when no model is presented
    other than the fit (a massless prior, a failed solve). ``B``: the structural base map (standard → base
    parameters); ``nonnegative``: indices held ≥ 0."""
    from ..parameters import check_physical_consistency

    fit, prior = np.asarray(fit, dtype=float), np.asarray(prior, dtype=float)
    p, nb = structure.n_params, structure.n_body_params
    P0 = prior[:nb].reshape(-1, 10)
    if not (P0[:, 0] > 0).any():
        return None, {"reason": "no inertial prior to move toward"}
    A, b, c = ne.total(None if row_weights is None else np.asarray(row_weights, dtype=float))
    d = np.sqrt(np.maximum(np.diag(A), 0.0))
    d = np.where(d > 1e-12 * max(d.max(), 1e-300), d, 1.0)
    Ah = A / np.outer(d, d)
    lam, V = np.linalg.eigh(0.5 * (Ah + Ah.T))
    keep = lam > 1e-10 * max(float(lam[-1]), 1e-300)
    y_star = V[:, keep] @ ((V[:, keep].T @ (b / d)) / lam[keep])  # the unconstrained minimiser, scaled
    R = np.sqrt(lam[keep])[:, None] * V[:, keep].T
    y_fit = fit * d
    rss = lambda y: float(np.sum((R @ (y - y_star)) ** 2))  # noqa: E731  RSS(π) − RSS(π*)
    s2 = float(verdicts["settings"]["residual_variance"])
    rank = int(keep.sum())
    physical_fit = all(r.consistent for r in check_physical_consistency(fit[:nb]))
    # a fit that is no physical body (least squares): the region that holds the truth at 95 %, χ²(rank)·s²
    budget = rss(y_fit) + s2 * REGION if physical_fit else s2 * _chi2_95(rank)
    if not s2 * REGION > 1e-12 * max(c, 1e-300):  # noise-free: no room beyond the solver's own error
        return None, {"reason": "the data leave no room around the fit (no residual)"}
    names = list(structure.robot.body_names)
    fixed = [k for k, bname in enumerate(names)
             if P0[k, 0] > 0 and verdicts["bodies"][bname]["mass"]["verdict"] != "data"]
    info: dict = {"objective": "pullback metric at the prior (½ tr((J0⁻¹ΔJ)²) per body)",
                  "region": f"RSS of the fit + {REGION:g} × s² (rank {rank})",
                  "rss_fit": rss(y_fit), "rss_budget": budget}
    M = np.zeros((p, p))  # the objective's metric on π (bodies with a prior), and its linear part
    for k in range(len(names)):
        if P0[k, 0] > 0:
            F = _body_factor(P0[k])
            M[10 * k:10 * k + 10, 10 * k:10 * k + 10] = F.T @ F
    Py = M / np.outer(d, d)
    qy = -(M @ prior) / d
    if p > nb:  # the vanishing tie of the joint terms to the fit
        Py[nb:, nb:] += _TIE * np.eye(p - nb)
        qy[nb:] -= _TIE * y_fit[nb:]
    Rn = R / np.sqrt(budget)  # the region as ‖·‖ ≤ 1: O(1) numbers for the solver
    program = _Program(2.0 * Py, 2.0 * qy, Rn, y_star, d, P0, names, nonnegative)

    out = program.solve([])
    if out is None:
        info["reason"] = "the program could not be solved: the fit is presented"
        return None, info
    info["rss"] = rss(out * d)
    out, kept = _prior_masses(out, B, P0, fixed)
    info["prior_mass_bodies"] = [names[k] for k in fixed if k in kept]
    rest = [names[k] for k in fixed if k not in kept]
    if rest:
        info["fallback"] = (f"with the prior's masses of {', '.join(rest)} no physical bodies give the presented "
                            "dynamics: the nearest model's masses are written for them")
    return out, info


def _prior_masses(pi: np.ndarray, B: np.ndarray, P0: np.ndarray, fixed: list[int]) -> tuple[np.ndarray, list[int]]:
    """Step 2: the prior's masses for the bodies ``fixed``, moving the inertials only along the structural null
    space ``B Δ = 0`` (no motion's torques change), every body physical, greedily farthest from the prior first
    (:func:`.urdf_values.reach_prior_masses`, :func:`.urdf_values.greedy_prefixes`)."""
    from .urdf_values import greedy_prefixes, reach_prior_masses

    nb = P0.size
    m = np.where(P0[:, 0] > 0, P0[:, 0], max(P0[:, 0].mean(), 1e-3))
    S = np.repeat(m, 10) * np.tile([1, 0.1, 0.1, 0.1] + [0.01] * 6, len(m))
    body = np.asarray(pi[:nb], dtype=float)
    order = sorted(fixed, key=lambda k: -abs(np.log(max(body[10 * k], 1e-12) / P0[k, 0])))

    def reach(ks: list[int]) -> np.ndarray | None:
        return reach_prior_masses(body, B[:, :nb], S, np.array(ks, dtype=int), P0[ks, 0])

    kept, moved = greedy_prefixes(order, reach)
    out = np.array(pi, dtype=float)
    if moved is not None:
        out[:nb] = moved
    return out, (kept if moved is not None else [])


def _chi2_95(df: int) -> float:
    """The 95 % quantile of χ² with ``df`` degrees of freedom (Wilson–Hilferty: within 1 % for df ≥ 3)."""
    k = max(int(df), 1)
    z = 1.6448536269514722
    return k * (1 - 2 / (9 * k) + z * np.sqrt(2 / (9 * k))) ** 3


class _Program:
    """The program of the module docstring in Clarabel's form ``min ½yᵀPy + qᵀy, Ay + s = b, s ∈ K`` (the variable
    ``y = d·π``): zero cone (the fixed masses), non-negative cone (the joint terms held ≥ 0), one second-order
    cone ``(1, Rn (y − y*))`` (the region) and one PSD cone per body (``svec`` of its pseudo-inertia, as
    :mod:`.prior_projection`)."""

    def __init__(self, P, q, Rn, y_star, d, P0, names, nonnegative):
        import scipy.sparse as sp

        from ..parameters import pseudo_inertia_basis
        from .prior_projection import svec

        self.P, self.q, self.d, self.P0, self.n = sp.csc_matrix(np.triu(P)), q, d, P0, len(d)
        p = len(d)
        nn = np.asarray(nonnegative if nonnegative is not None else [], dtype=int)
        basis = svec(pseudo_inertia_basis()).T  # (10 svec entries, 10 parameters)
        blocks = [sp.csc_matrix(-np.eye(p)[nn]) if nn.size else None,
                  sp.csc_matrix(np.vstack([np.zeros((1, p)), -Rn]))]
        rhs = [np.zeros(nn.size), np.concatenate([[1.0], -Rn @ y_star])]
        for k in range(len(names)):
            row = np.zeros((10, p))
            row[:, 10 * k:10 * k + 10] = -basis / d[10 * k:10 * k + 10]
            blocks.append(sp.csc_matrix(row))
            rhs.append(np.zeros(10))
        self.rest = sp.vstack([x for x in blocks if x is not None], format="csc")
        self.rest_b = np.concatenate(rhs)
        self.cones_rest = (nn.size, Rn.shape[0] + 1, len(names))

    def solve(self, fixed: list[int]) -> np.ndarray | None:
        import clarabel
        import scipy.sparse as sp

        E = np.zeros((len(fixed), self.n))
        for i, k in enumerate(fixed):
            E[i, 10 * k] = 1.0 / self.d[10 * k]
        A = sp.vstack([sp.csc_matrix(E), self.rest], format="csc")
        b = np.concatenate([self.P0[fixed, 0], self.rest_b])
        n_nn, n_soc, n_psd = self.cones_rest
        cones = ([clarabel.ZeroConeT(len(fixed))] if fixed else []) + \
                ([clarabel.NonnegativeConeT(n_nn)] if n_nn else []) + \
                [clarabel.SecondOrderConeT(n_soc)] + [clarabel.PSDTriangleConeT(4)] * n_psd
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        # tighter than the defaults (1e-8): the same equations compressed by another path give the same model
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-11
        try:
            sol = clarabel.DefaultSolver(self.P, self.q, A, b, cones, settings).solve()
        except (KeyboardInterrupt, SystemExit):
            raise
        except BaseException:  # noqa: BLE001 - a failed solve (a Clarabel panic is a BaseException): not reached
            return None
        if sol.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
            return None
        y = np.asarray(sol.x, dtype=float)
        if not np.all(np.isfinite(y)) or not self._feasible(y):
            return None
        return y / self.d

    def _feasible(self, y: np.ndarray, tol: float = 1e-6) -> bool:
        """An ``AlmostSolved`` point is kept only when it meets the cones to ``tol``: region, signs, bodies."""
        from ..parameters import pseudo_inertia

        s = self.rest_b - self.rest @ y
        n_nn, n_soc, _ = self.cones_rest
        if n_nn and s[:n_nn].min() < -tol:
            return False
        soc = s[n_nn:n_nn + n_soc]
        if np.linalg.norm(soc[1:]) > soc[0] * (1 + tol):
            return False
        pi = y / self.d
        for k in range(len(self.P0)):
            J = pseudo_inertia(pi[10 * k:10 * k + 10])
            if np.linalg.eigvalsh(0.5 * (J + J.T)).min() < -tol * max(abs(J).max(), 1e-12):
                return False
        return True

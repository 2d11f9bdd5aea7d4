"""The small SDP behind model.urdf's prior masses, assembled for Clarabel's own Python API.

In the scaled parameters ``x = π̂/S + y`` (``S``: per-body mass/length scales)::

    min ‖y‖²  (or ‖x − t/S‖² for a target t)
    s.t.  B diag(S) y = 0,   x[10k] = m0_k / S[10k] (k fixed),   J(x_k) ⪰ 0 for every body k

``J`` the 4×4 pseudo-inertia (:func:`sensorless.parameters.pseudo_inertia_basis`), congruent to the
unscaled one, so the cone is the same. As Clarabel's QP ``min ½vᵀPv + qᵀv, Av + s = b, s ∈ K``:
``v = y``, ``P = 2I``, ``q = 0``; with a target ``v = (z, y)`` and ``z = y + (π̂ − t)/S`` as n more
equalities, ``P = diag(2I, 0)``. ``K`` = a zero cone (the equalities) × one ``PSDTriangleConeT(4)``
per body, whose ``s = svec(J)``: the upper triangle by columns, off-diagonal entries × √2
(``svec(J)ᵀsvec(K) = tr(JK)``). These are, entry for entry and with the same sparsity, the data cvxpy
1.9 compiled the program to for Clarabel (a test checks it), so model.urdf is unchanged to the bit.

Why not cvxpy (kept as the tests' oracle): ``import cvxpy`` costs ~0.7 s after NumPy (it pulls ``scipy.stats``)
and cvxpy rebuilt and recompiled each solve (~25 ms a solve, 6–18 solves a model.urdf): on the
600-sample UR5 hard-case log, choosing model.urdf's values took 0.45 s of ``sensorless identify
--method ols`` (which needs cvxpy for nothing else) and 0.12 s of the LMI default; here 0.05 s and
0.02 s (``import clarabel``: ~10 ms; a solve: ~3 ms).
"""

from __future__ import annotations

import numpy as np

__all__ = ["conic_data", "solve_prior_projection", "svec"]

_ROWS, _COLS = np.triu_indices(4)
_ORDER = np.lexsort((_ROWS, _COLS))  # upper triangle by columns: (0,0), (0,1), (1,1), (0,2), …
_TRI_R, _TRI_C = _ROWS[_ORDER], _COLS[_ORDER]
_SVEC_SCALE = np.where(_TRI_R == _TRI_C, 1.0, np.sqrt(2.0))


def svec(J: np.ndarray) -> np.ndarray:
    """Clarabel's packing of symmetric ``(..., 4, 4)`` matrices: ``(..., 10)``."""
    return J[..., _TRI_R, _TRI_C] * _SVEC_SCALE


def conic_data(pi, B, S, fix, m0, target=None):
    """Clarabel's ``(P, q, A, b, (zero rows, PSD cones))`` for the program above (``fix``: body
    indices, ``m0``: their masses). Without target the variable is ``y``; with one it is ``(z, y)``,
    ``z = y + (π̂ − t)/S`` tied by n more equalities and ``‖z‖²`` minimised: the form cvxpy compiled
    the program to, kept so that model.urdf's values did not move with the change of route."""
    import scipy.sparse as sp

    from ..parameters import pseudo_inertia_basis

    pi, S = np.asarray(pi, dtype=float), np.asarray(S, dtype=float)
    fix, m0 = np.asarray(fix, dtype=int).ravel(), np.asarray(m0, dtype=float).ravel()
    n = len(pi)
    nb = n // 10
    x0 = pi / S
    # equalities: B diag(S) y = 0; y[10k] = m0_k/S[10k] − x0[10k]
    E = np.asarray(B, dtype=float) * S[None, :]
    F = sp.csc_matrix((np.ones(len(fix)), (np.arange(len(fix)), 10 * fix)), shape=(len(fix), n))
    # cones: s_k = svec(J(x0_k + y_k)) = svec(J(x0_k)) − A_k y_k with A_k = −[svec(A_i)]_i
    basis = svec(pseudo_inertia_basis()).T  # (10 svec entries, 10 parameters)
    A = sp.vstack([sp.csc_matrix(E), F, sp.block_diag([-basis] * nb)], format="csc")
    b = np.concatenate([np.zeros(len(E)), m0 / S[10 * fix] - x0[10 * fix], (x0.reshape(nb, 10) @ basis.T).ravel()])
    A.eliminate_zeros()  # Clarabel keeps stored zeros in its KKT pattern
    n_zero = A.shape[0] - 10 * nb
    if target is None:
        return 2.0 * sp.identity(n, format="csc"), np.zeros(n), A, b, (n_zero, nb)
    # (z, y): −z + y = −(π̂ − t)/S, then the rows above on y
    tie = sp.hstack([-sp.identity(n), sp.identity(n)])
    A = sp.vstack([tie, sp.hstack([sp.csc_matrix(A.shape), A])], format="csc")
    b = np.concatenate([np.asarray(target, dtype=float) / S - x0, b])
    P = sp.block_diag([2.0 * sp.identity(n), sp.csc_matrix((n, n))], format="csc")
    return P, np.zeros(2 * n), A, b, (n + n_zero, nb)


def solve_prior_projection(pi, B, S, fix, m0, target=None) -> np.ndarray | None:
    """The minimiser ``y`` of the program above, or None unless Clarabel reports ``Solved`` (an
    ``AlmostSolved`` is rejected, as cvxpy's ``OPTIMAL_INACCURATE`` was) or for non-finite data (which
    cvxpy refused)."""
    import clarabel

    with np.errstate(invalid="ignore", over="ignore"):
        P, q, A, b, (n_zero, nb) = conic_data(pi, B, S, fix, m0, target)
    if not (np.isfinite(A.data).all() and np.isfinite(b).all()):  # Clarabel's presolve would drop such rows
        return None
    cones = [clarabel.ZeroConeT(n_zero)] + [clarabel.PSDTriangleConeT(4)] * nb
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    try:
        sol = clarabel.DefaultSolver(P, q, A, b, cones, settings).solve()
    except (ValueError, ArithmeticError, RuntimeError):
        return None
    if sol.status != clarabel.SolverStatus.Solved:
        return None
    y = np.asarray(sol.x, dtype=float)[-len(pi):]
    return y if np.isfinite(y).all() else None

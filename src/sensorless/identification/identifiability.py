"""Which base parameters a given data set (gait, trajectory) actually excites.

With the structural base parameters π_b = B π (``base_parameters``) and the data's normal
matrix restricted to them, A₁₁ = A[ind, ind], equilibrate S = D A₁₁ D (D = diag(A₁₁)^-½)
and eigendecompose S = U Λ Uᵀ. Directions with √λ < rcond·√λ_max are not excited: no
amount of this kind of data identifies them. Each such direction is reported by the
base parameters that dominate its eigenvector.
"""

from __future__ import annotations

import numpy as np

from ..regressor.normal_equations import NormalEquations
from .base import BaseParameters

__all__ = ["identifiability_report"]


def identifiability_report(ne: NormalEquations, base: BaseParameters, rcond: float = 1e-6, top: int = 3) -> dict:
    A, _, _ = ne.total()
    ind = base.independent
    A11 = A[np.ix_(ind, ind)]
    d = np.sqrt(np.maximum(np.diag(A11), 0.0))  # a column that is zero can sum to -1e-13
    expr = base.expressions()
    zero = d <= 1e-12 * max(d.max(), 1e-300)
    d[zero] = 1.0
    S = A11 / np.outer(d, d)
    S[zero, :] = 0.0
    S[:, zero] = 0.0
    lam, U = np.linalg.eigh(S)
    sv = np.sqrt(np.maximum(lam, 0.0))
    smax = sv.max() if sv.size else 0.0
    weak = np.flatnonzero(sv <= rcond * smax)
    unexcited = []
    for k in weak:
        order = np.argsort(-np.abs(U[:, k]))[:top]
        unexcited.append({"singular_value_ratio": float(sv[k] / smax) if smax else 0.0,
                          "dominant_base_parameters": [expr[i] for i in order]})
    excited = sv > rcond * smax
    cond = float(smax / sv[excited].min()) if excited.any() else float("inf")
    return {
        "n_base_structural": base.rank,
        "n_base_excited": int(excited.sum()),
        "condition_number_excited": cond,
        "rcond": rcond,
        "not_excited": unexcited,
        "n_samples": ne.n_samples,
    }

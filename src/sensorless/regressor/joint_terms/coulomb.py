"""``fc``: Coulomb friction, τ_j += fc_j T_j with T = tanh(v/ε) (sgn v for ε = 0; 0 at rest, |v| ≤ δ;
:mod:`..friction_columns`). fc ≥ 0."""

from __future__ import annotations

import numpy as np

from .base import JointTerm, TermInputs

__all__ = ["COULOMB"]


def _column(x: TermInputs) -> np.ndarray:
    """Column T (:attr:`TermInputs.coulomb_sign`)."""
    return x.coulomb_sign


COULOMB = JointTerm("fc", "Coulomb friction fc·tanh(v/ε) (sgn v for ε = 0)", _column,
                    passive=True, nonnegative=True, reversal=True, exported=True)

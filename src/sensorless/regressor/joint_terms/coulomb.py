"""``fc``: Coulomb friction, τ_j += fc_j T_j with T = tanh(v/ε) (sgn v for ε = 0; 0 at rest, |v| ≤ δ;
:mod:`..friction_columns`). fc ≥ 0."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import TermInputs

__all__ = ["Coulomb"]


@dataclass(frozen=True)
class Coulomb:
    """Column T (:attr:`TermInputs.coulomb_sign`)."""

    name = "fc"
    description = "Coulomb friction fc·tanh(v/ε) (sgn v for ε = 0)"
    passive = True
    needs_motion = True
    acceleration = False
    nonnegative = True
    reversal = True
    stateful = False
    exported = True

    def column(self, x: TermInputs) -> np.ndarray:
        return x.coulomb_sign

"""``fv``: viscous friction, τ_j += fv_j v_j (fv ≥ 0)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import TermInputs

__all__ = ["Viscous"]


@dataclass(frozen=True)
class Viscous:
    """Column v."""

    name = "fv"
    description = "viscous friction fv·v"
    passive = True
    needs_motion = True
    acceleration = False
    nonnegative = True
    reversal = False
    stateful = False
    exported = True

    def column(self, x: TermInputs) -> np.ndarray:
        return x.v

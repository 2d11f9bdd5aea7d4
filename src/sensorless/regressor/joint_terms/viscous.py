"""``fv``: viscous friction, τ_j += fv_j v_j (fv ≥ 0)."""

from __future__ import annotations

import numpy as np

from .base import JointTerm, TermInputs

__all__ = ["VISCOUS"]


def _column(x: TermInputs) -> np.ndarray:
    """Column v."""
    return x.v


VISCOUS = JointTerm("fv", "viscous friction fv·v", _column, passive=True, nonnegative=True, exported=True)

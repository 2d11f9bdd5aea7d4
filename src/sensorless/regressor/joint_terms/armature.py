"""``armature``: reflected rotor inertia, τ_j += Ia_j v̇_j (Ia ≥ 0; an actuated joint only: a passive
joint has no rotor). In the acceleration-free form its momentum column is v (:mod:`..integral`)."""

from __future__ import annotations

import numpy as np

from .base import JointTerm, TermInputs

__all__ = ["ARMATURE"]


def _column(x: TermInputs) -> np.ndarray:
    """Column v̇."""
    return x.a


ARMATURE = JointTerm("armature", "reflected rotor inertia Ia·v̇", _column,
                     acceleration=True, nonnegative=True, exported=True)

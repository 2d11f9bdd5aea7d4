"""``armature``: reflected rotor inertia, τ_j += Ia_j v̇_j (Ia ≥ 0; an actuated joint only: a passive
joint has no rotor). In the acceleration-free form its momentum column is v (:mod:`..integral`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import TermInputs

__all__ = ["Armature"]


@dataclass(frozen=True)
class Armature:
    """Column v̇."""

    name = "armature"
    description = "reflected rotor inertia Ia·v̇"
    passive = False
    needs_motion = True
    acceleration = True
    nonnegative = True
    reversal = False
    stateful = False
    exported = True

    def column(self, x: TermInputs) -> np.ndarray:
        return x.a

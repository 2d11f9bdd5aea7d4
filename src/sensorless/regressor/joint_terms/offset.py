"""``offset``: a constant torque offset of the joint's measurement, τ_j += o_j (an actuated joint only:
a passive joint has no torque sensor to be offset)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import TermInputs

__all__ = ["Offset"]


@dataclass(frozen=True)
class Offset:
    """Column 1."""

    name = "offset"
    description = "constant torque offset o"
    passive = False
    needs_motion = False
    acceleration = False
    nonnegative = False
    reversal = False
    stateful = False
    exported = True

    def column(self, x: TermInputs) -> np.ndarray:
        return np.ones_like(x.v)

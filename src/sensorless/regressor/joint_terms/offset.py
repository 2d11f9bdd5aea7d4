"""``offset``: a constant torque offset of the joint's measurement, τ_j += o_j (an actuated joint only:
a passive joint has no torque sensor to be offset)."""

from __future__ import annotations

import numpy as np

from .base import JointTerm, TermInputs

__all__ = ["OFFSET"]


def _column(x: TermInputs) -> np.ndarray:
    """Column 1."""
    return np.ones_like(x.v)


OFFSET = JointTerm("offset", "constant torque offset o", _column, needs_motion=False, exported=True)

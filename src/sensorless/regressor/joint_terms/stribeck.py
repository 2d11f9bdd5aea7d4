"""``stribeck``: the static friction above Coulomb, parameter fs − fc (any sign before the search keeps it).

Friction law "blend" (written since the transition width is fitted):

    τ_f = fs T − (fs − fc)(1 − e^{−(v/vs)²}) sgn v = fc T + (fs − fc) [T − (1 − e^{−(v/vs)²}) sgn v],

column T − (1 − e^{−(v/vs)²}) sgn v (:func:`..friction_columns.stribeck_decay`; sgn v is 0 at rest).
Law "product" (older models, read from result.json files): column e^{−(v/vs)²} T. vs per joint
(:attr:`TermInputs.vs`); :mod:`sensorless.identification.stribeck` chooses it and the width ε.
"""

from __future__ import annotations

import numpy as np

from ..friction_columns import stribeck_decay
from .base import JointTerm, TermInputs

__all__ = ["FRICTION_LAWS", "STRIBECK"]

#: forms of the Stribeck column (module docstring)
FRICTION_LAWS = ("blend", "product")


def _column(x: TermInputs) -> np.ndarray:
    """Column T − (1 − e^{−(v/vs)²}) sgn v ("blend") or e^{−(v/vs)²} T ("product")."""
    if x.friction_law == "product":
        return np.exp(-((x.v / x.vs) ** 2)) * x.coulomb_sign
    return x.coulomb_sign - stribeck_decay(x.v, x.vs, x.sliding_sign)


STRIBECK = JointTerm("stribeck", "Stribeck friction (fs − fc)·[T − (1 − exp(−(v/vs)²)) sgn v]", _column,
                     passive=True, reversal=True, exported=True)

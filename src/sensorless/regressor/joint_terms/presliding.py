"""``presliding`` (opt-in): the presliding state s_c of :mod:`..friction_state` along each log from 0,
τ_j += φ_j s_c (:meth:`~sensorless.regressor.terms.ModelStructure.friction_states`). It depends on the
history of q, so it is evaluated on whole logs; steady sliding gives s_c = sgn v. Its amplitude,
presliding distance and play live in result.json only (a URDF has no friction state)."""

from __future__ import annotations

import numpy as np

from ...errors import DataError
from .base import JointTerm, TermInputs

__all__ = ["PRESLIDING"]


def _column(x: TermInputs) -> np.ndarray:
    """Column s_c (:attr:`TermInputs.z`)."""
    if x.z is None or np.shape(x.z) != x.v.shape:
        raise DataError("the 'presliding' term depends on the history of q: evaluate whole logs (regressor, torques)")
    return np.asarray(x.z, dtype=float)


PRESLIDING = JointTerm("presliding", "presliding state s_c (Dahl/LuGre type, whole logs)", _column, stateful=True)

"""``fv_asym`` (opt-in): direction-dependent viscous friction, τ_j += fv_asym_j |v_j|.

With ``fv`` the joint's viscous friction is fv⁺ v for v > 0 and fv⁻ v for v < 0,

    fv v + fv_asym |v|,   fv⁺ = fv + fv_asym,   fv⁻ = fv − fv_asym,

as harmonic drives show (the flexspline's losses differ with the direction of the load). The
column |v| is continuous at a reversal (no equation is left out for it). fv_asym has either sign;
fv⁺, fv⁻ ≥ 0 is not imposed by the consistent fit (check them in result.json).
"""

from __future__ import annotations

import numpy as np

from .base import JointTerm, TermInputs

__all__ = ["VISCOUS_ASYMMETRY"]


def _column(x: TermInputs) -> np.ndarray:
    """Column |v|."""
    return np.abs(x.v)


VISCOUS_ASYMMETRY = JointTerm("fv_asym", "direction-dependent viscous friction fv_asym·|v| (fv± = fv ± fv_asym)",
                              _column, passive=True)

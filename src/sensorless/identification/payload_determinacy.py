"""Which payload quantities a log determines (:mod:`.payload`): the mass m, the first moment
m·c and the rotational inertia, from the frame's payload regressor over the log.

The torque a payload adds is Jᵀ Φ_f φ. Its mass column is J_vᵀ (a_O − g): the translational
Jacobian of the frame origin O. Where O does not move under the logged joints (a remote
centre of motion, a frame on a joint axis), that column vanishes and only m·c (through the
rotation, J_ωᵀ (c × m g)) and the inertia about O reach the joints: m is not determined,
and a fit of m is noise over noise. Where O moves but only along the directions m·c also
explains (a pendulum: m d + h_x), m and m·c cannot be separated either. Both show as a
small Schur complement of the mass in the [m, m·c] block of the normal matrix, measured as
a lever arm: √(s_m / λ_max) [m], the part of the mass column the first-moment columns do
not explain, relative to one metre of them. The inertia needs angular acceleration: the
existing excitation measure of the inertia block decides it.

Verdicts: ``"data"`` (the log determines it), ``"undetermined"``, ``"from the given CoM"``
(m from m·c and a CoM the user gave: --com, or the frame origin in mode mass), ``"at bound: not determined"`` (the estimate sits at m = 0,
the bound of the fit), ``"assumed (point mass)"`` (inertia in modes com/mass).
"""

from __future__ import annotations

import numpy as np

__all__ = ["LEVER_TOL", "first_moment_lever", "mass_lever"]

LEVER_TOL = 5e-3
"""[m] A mass column whose independent part is below this lever arm does not determine m (a frame
that only rotates about a fixed point separates m from m·c through accelerations alone: ~1 mm)."""


def _lam_max(A: np.ndarray) -> float:
    return max(float(np.linalg.eigvalsh(A[:4, :4])[-1]), 1e-300)


def mass_lever(A: np.ndarray) -> float:
    """√(s_m / λ_max) [m]: the mass column's part not explained by the m·c columns (module
    docstring), from the reduced normal matrix A (10 × 10, φ = [m, m c, I])."""
    B = A[:4, :4]
    s_m = float(B[0, 0] - B[0, 1:] @ np.linalg.pinv(B[1:, 1:], rcond=1e-13) @ B[1:, 0])
    return float(np.sqrt(max(s_m, 0.0) / _lam_max(A)))


def first_moment_lever(A: np.ndarray, mass_known: bool) -> float:
    """Smallest singular direction of the m·c block, relative to the largest of [m, m·c]
    (dimensionless, √ of the eigenvalue ratio); with the mass free (``mass_known`` False) the
    mass is profiled out first."""
    B = A[:4, :4]
    S = B[1:, 1:]
    if not mass_known and B[0, 0] > 1e-12 * _lam_max(A):  # a vanishing mass column: nothing to profile
        S = S - np.outer(B[1:, 0], B[0, 1:]) / B[0, 0]
    return float(np.sqrt(max(float(np.linalg.eigvalsh(S)[0]), 0.0) / _lam_max(A)))


def verdicts(A: np.ndarray, *, mode: str, inertia_excitation: float, inertia_threshold: float,
             mass_from_com: bool) -> dict:
    """Per quantity ("mass", "first_moment", "inertia"): its verdict, and the measures behind them."""
    lever = mass_lever(A)
    fm = first_moment_lever(A, mass_known=lever >= LEVER_TOL)
    mass = "from the given CoM" if mass_from_com else ("data" if lever >= LEVER_TOL else "undetermined")
    if mode in ("com", "mass"):
        inertia = "assumed (point mass)"
    else:
        inertia = "data" if inertia_excitation > inertia_threshold else "undetermined"
    return {"mass": mass, "first_moment": "data" if fm >= LEVER_TOL else "undetermined", "inertia": inertia,
            "mass_lever_m": lever, "first_moment_excitation": fm, "inertia_excitation": float(inertia_excitation),
            "lever_tolerance_m": LEVER_TOL}

"""Legged contact forces from joint torques and the identified model (no force sensing).

Whole-body dynamics with forces f_i at the stance feet (Jacobians J_i, LOCAL_WORLD_ALIGNED):

    M v̇ + h + Sᵀ τ_f = Sᵀ τ + Σ_i J_iᵀ f_i.

Per sample, the forces of the feet in contact solve the least-squares problem

    f = argmin ‖Jcᵀ f − τ_ext‖²,   Jc = stacked J_i of the stance feet,

with the external generalised force τ_ext from either

* ``method="momentum"`` (default, no accelerations): the momentum observer's r ≈ L(s)[Jcᵀ f]
  (:mod:`.momentum`), so the forces are those through the observer's low-pass L; or
* ``method="inverse_dynamics"``: τ_ext = M v̇ + h + Sᵀτ_f − Sᵀτ with the log's v̇ (Pinocchio RNEA).

The 6 base rows make the problem well posed for up to two point feet (6 unknowns) and
least squares beyond (the joint rows add 3 equations per leg, so 4 stance feet give 12
unknowns for 18 equations). Stance comes from the log's contact flags, or (``flags="detect"``)
from a first solve with all feet: a foot is in stance when its vertical force exceeds
``threshold``, then the problem is solved again with those feet.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError, setting
from ..regressor.contact_kinematics import contact_jacobians
from .momentum import MomentumDynamics, MomentumObserver

__all__ = ["ContactForceEstimate", "estimate_contact_forces", "solve_contact_forces"]


@dataclass
class ContactForceEstimate:
    t: np.ndarray
    forces: np.ndarray  # (N, n_feet, 3), world axes, zero for swing feet
    contact: np.ndarray  # (N, n_feet) bool: stance used in the solve
    frames: tuple[str, ...]
    tau_ext: np.ndarray  # (N, nv)
    residual: np.ndarray  # (N,) ‖Jcᵀ f − τ_ext‖
    settings: dict = field(default_factory=dict)


def solve_contact_forces(Jc: np.ndarray, tau_ext: np.ndarray, contact: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched least squares f = (Jcᵀ)⁺ τ_ext for Jc (N, 3 n_feet, nv) with swing rows zeroed.

    Returns (forces (N, n_feet, 3), residual norms (N,)). Zero rows get zero force.
    """
    N, m, nv = Jc.shape
    Jm = Jc * np.repeat(contact, 3, axis=1)[:, :, None]
    F = np.einsum("nmi,ni->nm", np.linalg.pinv(Jm.transpose(0, 2, 1), rcond=1e-8), tau_ext)
    res = np.linalg.norm(np.einsum("nmi,nm->ni", Jm, F) - tau_ext, axis=1)
    return F.reshape(N, m // 3, 3), res


def estimate_contact_forces(
    dynamics: MomentumDynamics,
    traj: Trajectory,
    frames: Sequence[str],
    *,
    flags: np.ndarray | str | None = None,
    method: str = "momentum",
    gain: float = 200.0,
    order: int = 1,
    contact_offset: float = 0.0,
    threshold: float | None = None,
) -> ContactForceEstimate:
    """Per-foot contact forces of a floating-base log (see the module docstring).

    ``flags``: (N, n_feet) bool, None (the log's ``extras["contact"]``) or ``"detect"``.
    ``contact_offset``: radius of spherical feet (the force acts that far below the frame).
    ``threshold`` [N]: vertical force of a detected stance foot (default 5 % of the weight).
    ``gain`` K [1/s] of the observer: a trot's stance forces change within ~0.1 s, so K is
    higher than for collision monitoring (measured on the simulated Solo12 trot at 100 Hz:
    vertical RMSE 5–8 % of the weight with K = 200, 9–13 % with K = 50).
    """
    if not dynamics.floating_base or dynamics.transmission:
        raise RobotModelError("contact forces need a floating-base model")
    robot = dynamics.structure.robot
    frames = tuple(frames)
    fids = [robot.frame_id(f) for f in frames]
    if method == "momentum":
        res = MomentumObserver(dynamics, gain=gain, order=order).run(traj)
        tau_ext = res.r
        Q = dynamics.arrays(traj)[0]
    elif method == "inverse_dynamics":
        Q, V, tau = dynamics.arrays(traj)
        tr = dynamics._ordered(traj)
        if tr.a is None or tr.base_a is None:
            raise DataError("method 'inverse_dynamics' needs joint and base accelerations (a, base_a)", traj.source)
        A = robot.full_velocity(tr.a, tr.base_a)
        model, data = dynamics.model, dynamics.data
        lhs = np.array([pin.rnea(model, data, Q[i], V[i], A[i]) for i in range(len(tr))])
        tau_ext = lhs + dynamics.friction(Q, V) - tau
    else:
        raise RobotModelError(f"method must be 'momentum' or 'inverse_dynamics', got {method!r}")
    N = Q.shape[0]
    detect = isinstance(flags, str)
    if detect and flags != "detect":
        raise DataError(f"flags must be an array, None or 'detect', got {flags!r}", traj.source)
    if flags is None:
        flags = traj.extras.get("contact")
        if flags is None:
            raise DataError(f"the log has no contact flags (extras['contact']); detect them: {setting('flags', 'detect')}", traj.source)
    if detect:
        flags = np.ones((N, len(frames)), bool)
    flags = np.asarray(flags, bool)
    if flags.shape != (N, len(frames)):
        raise DataError(f"contact flags have shape {flags.shape}, expected ({N}, {len(frames)}) for {list(frames)}",
                        traj.source)
    Jc = contact_jacobians(robot, fids, (3,) * len(frames), Q, np.ones_like(flags), contact_offset)
    F, resid = solve_contact_forces(Jc, tau_ext, flags)
    if detect:
        if threshold is None:
            mass = sum(dynamics.model.inertias[j].mass for j in range(1, dynamics.model.njoints))
            threshold = 0.05 * mass * np.linalg.norm(dynamics.model.gravity.linear)
        flags = F[:, :, 2] > threshold
        F, resid = solve_contact_forces(Jc, tau_ext, flags)
    bad = ~np.all(np.isfinite(F.reshape(len(F), -1)), axis=1)
    if bad.any():
        raise DataError(f"the contact forces are not finite on {int(bad.sum())} of {len(F)} samples (first: sample "
                        f"{int(np.flatnonzero(bad)[0])}); the model or the log holds non-finite values", traj.source)
    return ContactForceEstimate(traj.t, F, flags, frames, tau_ext, resid,
                                {"method": method, "gain": gain, "order": order, "contact_offset": contact_offset,
                                 "flags": "detect" if detect else "log", "threshold": threshold})

"""Contact kinematics for the contact row maps (:mod:`.contact`): stacked contact Jacobians,
foot rotations, contact detection from foot height and speed, and the null-space projector
P = I − Jc⁺Jc and orthonormal bases B of null(Jc) (P = B Bᵀ), batched over samples.

Jacobians are Pinocchio ``getFrameJacobian`` in LOCAL_WORLD_ALIGNED; point contacts use
the 3 linear rows, 6-D (flat-foot) contacts all 6.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError

__all__ = ["contact_jacobians", "contact_rotations", "detect_contacts", "null_space_basis", "null_space_projector"]


def null_space_projector(Jc: np.ndarray, rcond: float = 1e-8, method: str = "cholesky") -> np.ndarray:
    """Batched P = I − Jc⁺Jc for Jc of shape (N, m, nv); zero or dependent rows are allowed.

    ``method="cholesky"`` (default, fast): G = Jc Jcᵀ + ε I with ε = rcond²·tr(G), G = L Lᵀ,
    X = L⁻¹ Jc, P = I − XᵀX. The damping gives each singular direction the weight
    s²/(s² + ε): exact for s = 0 (dependent rows, inactive feet) and for s² ≫ ε, a smooth
    blend in between. Vectorised over samples (loop over the m contact rows only).
    ``method="svd"``: P = I − V_r V_rᵀ with singular values above rcond·σ_max (exact cut-off).
    """
    N, m, nv = Jc.shape
    if m == 0:
        return np.broadcast_to(np.eye(nv), (N, nv, nv)).copy()
    if method == "svd":
        _, s, Vt = np.linalg.svd(Jc, full_matrices=False)
        smax = s[:, :1]
        keep = (s > rcond * np.maximum(smax, 1e-300)) & (smax > 0)
        Vr = Vt * keep[:, :, None]
        return np.eye(nv) - np.einsum("nki,nkj->nij", Vr, Vr)
    G = np.matmul(Jc, Jc.transpose(0, 2, 1))
    eps = rcond**2 * np.maximum(np.trace(G, axis1=1, axis2=2), 1e-300)
    L = np.zeros_like(G)
    X = np.empty_like(Jc)
    for j in range(m):  # column-wise Cholesky and forward substitution, vectorised over N (batched matmul:
        Lj = L[:, j, None, :j]  # several times faster than einsum on these small stacked matrices)
        ljj = np.sqrt(np.maximum(G[:, j, j] + eps - np.matmul(Lj, Lj.transpose(0, 2, 1))[:, 0, 0], eps))
        L[:, j, j] = ljj
        if j + 1 < m:
            L[:, j + 1 :, j] = (G[:, j + 1 :, j] - np.matmul(L[:, j + 1 :, :j], Lj.transpose(0, 2, 1))[:, :, 0]) / ljj[:, None]
        X[:, j] = (Jc[:, j] - np.matmul(Lj, X[:, :j])[:, 0]) / ljj[:, None]
    P = -np.matmul(X.transpose(0, 2, 1), X)
    P[:, np.arange(nv), np.arange(nv)] += 1.0
    return P


def null_space_basis(Jc: np.ndarray, rcond: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal bases B (N, nv, nv − m) of null(Jc) for Jc (N, m, nv), and where they equal the projector.

    Householder QR of Jcᵀ = Q R (LAPACK, batched over samples): B is the last nv − m columns of Q,
    so Jc B = 0, BᵀB = I and B Bᵀ = I − Jc⁺Jc for Jc of full row rank. ``exact`` (N,) marks the
    samples where B Bᵀ also equals :func:`null_space_projector` (damping ε = rcond²·‖Jc‖²_F) to
    1e-8: σ_min(Jc) ≥ 1/‖R⁻¹‖_F ≥ 1e4·rcond·‖Jc‖_F, so ε/σ²_min ≤ 1e-8. Elsewhere (dependent or
    nearly dependent rows, m ≥ nv) B spans only part of the null space: use the projector there.
    """
    N, m, nv = Jc.shape
    if m == 0:
        return np.broadcast_to(np.eye(nv), (N, nv, nv)).copy(), np.ones(N, bool)
    if m >= nv or N == 0:
        return np.zeros((N, nv, max(nv - m, 0))), np.zeros(N, bool)
    Q, R = np.linalg.qr(Jc.transpose(0, 2, 1), mode="complete")  # Q (N, nv, nv), R (N, nv, m)
    R = R[:, :m, :]
    piv = np.abs(R[:, np.arange(m), np.arange(m)])
    scale = np.sqrt(np.einsum("nij,nij->n", Jc, Jc))
    ok = piv.min(axis=1) > 1e4 * rcond * scale
    R_safe = np.where(ok[:, None, None], R, np.eye(m))
    Rinv = np.linalg.inv(R_safe)
    inv_norm = np.sqrt(np.einsum("nij,nij->n", Rinv, Rinv))
    exact = ok & (1.0 / inv_norm >= 1e4 * rcond * scale)
    return Q[:, :, m:], exact


_EZ_CROSS = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])


def contact_jacobians(
    robot, frames: Sequence[int], dims: Sequence[int], Q: np.ndarray, active: np.ndarray, offset: float = 0.0
) -> np.ndarray:
    """Stacked contact Jacobians (N, Σ dims, nv); rows of inactive contacts are zero.

    ``offset`` ρ moves a point contact from the frame to ρ below it along world z (the
    bottom of a spherical foot of radius ρ): v_c = v_f + ω × (−ρ e_z) = v_f + ρ [e_z]× ω.
    """
    model, data = robot.model, robot.data
    N = Q.shape[0]
    m = int(sum(dims))
    J = np.zeros((N, m, robot.nv))
    offsets = np.concatenate([[0], np.cumsum(dims)])
    rows_needed = active.any(axis=1)
    for i in np.flatnonzero(rows_needed):
        pin.computeJointJacobians(model, data, Q[i])
        for k, (fid, d) in enumerate(zip(frames, dims)):
            if active[i, k]:
                Jk = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
                if d == 3:
                    J[i, offsets[k] : offsets[k + 1]] = Jk[:3] + offset * (_EZ_CROSS @ Jk[3:]) if offset else Jk[:3]
                else:
                    J[i, offsets[k] : offsets[k + 1]] = Jk
    return J


def contact_rotations(robot, frames: Sequence[int], Q: np.ndarray) -> np.ndarray:
    """World rotations R_k (N, n_frames, 3, 3) of contact frames (sole axes in world axes)."""
    model, data = robot.model, robot.data
    R = np.empty((Q.shape[0], len(frames), 3, 3))
    for i in range(Q.shape[0]):
        pin.framesForwardKinematics(model, data, Q[i])
        for k, fid in enumerate(frames):
            R[i, k] = data.oMf[fid].rotation
    return R


def detect_contacts(
    robot,
    traj: Trajectory,
    frames: Sequence[str],
    *,
    height: float = 0.02,
    speed: float = 0.1,
    ground: float | None = None,
) -> np.ndarray:
    """Contact flags (N, n_frames) from foot height and speed when a log has no flags.

    A frame is in contact when it is within ``height`` of the ground (default: the 2nd
    percentile of all foot heights, i.e. the floor as seen in the log) and its world
    velocity is below ``speed``. A floating base needs the base pose and twist (``base_q``, ``base_v``).
    """
    if robot.floating_base and (traj.base_q is None or traj.base_v is None):
        raise DataError("contact detection needs base_q and base_v (base pose and twist)", traj.source)
    model, data = robot.model, robot.data
    fids = [robot.frame_id(f) for f in frames]
    Q = robot.full_configuration(traj.q, traj.base_q)
    V = robot.full_velocity(traj.v, traj.base_v)
    z = np.empty((len(traj), len(fids)))
    sp = np.empty_like(z)
    for i in range(len(traj)):
        pin.forwardKinematics(model, data, Q[i], V[i])
        for k, fid in enumerate(fids):
            z[i, k] = pin.updateFramePlacement(model, data, fid).translation[2]
            sp[i, k] = np.linalg.norm(pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear)
    floor = np.percentile(z, 2) if ground is None else ground
    return (z - floor < height) & (sp < speed)

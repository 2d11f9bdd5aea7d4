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
from . import native

__all__ = ["contact_jacobians", "contact_rotations", "detect_contacts", "null_space_basis", "null_space_projector"]


#: Largest condition bound ‖Jc‖_F ‖L⁻¹‖_F taken through the normal equations: their error is about
#: eps·κ² (2e-11 at κ = 10³) against the SVD's eps·κ; worse-conditioned samples go to the SVD.
FAST_CONDITION = 1e3
#: Work-array budget of one NumPy chunk (doubles, 2 MiB): J, P, G and L⁻¹ of the chunk stay in cache.
_CHUNK_DOUBLES = 1 << 18


def null_space_projector(Jc: np.ndarray, rcond: float = 1e-8, method: str = "cholesky") -> np.ndarray:
    """Batched P = I − Jc⁺Jc for Jc of shape (N, m, nv), with the rank cut-off of
    ``numpy.linalg.pinv(Jc[i], rcond)``: singular values ≤ rcond·σ_max are dropped.

    ``method="cholesky"`` (default, fast): G = Jc Jcᵀ = L Lᵀ (batched LAPACK), L⁻¹ by a
    forward substitution vectorised over samples, X = L⁻¹ Jc and P = I − XᵀX (= I − Jcᵀ G⁻¹ Jc).
    Exactly zero rows (inactive contacts) get G_jj = ‖Jc‖²_F, so they add nothing. A sample is
    taken this way only when σ_min ≥ 1/‖L⁻¹‖_F certifies that pinv keeps every row
    (‖Jc‖_F ‖L⁻¹‖_F < 1/rcond) and that the normal equations are accurate
    (≤ :data:`FAST_CONDITION`); the others (dependent or nearly dependent rows) get the SVD.
    ``method="svd"``: P = I − V_r V_rᵀ for every sample, V_r the right singular vectors kept.
    Both equal the per-sample pinv to about 1e-11. The Cholesky route runs in the optional C++ kernel
    (:func:`~.native.contact_projector`) when it is built, else in NumPy over cache-sized chunks.
    """
    Jc = np.asarray(Jc, dtype=float)
    if method not in ("cholesky", "svd"):
        raise ValueError(f"unknown projector method '{method}'; use 'cholesky' or 'svd'")
    N, m, nv = Jc.shape
    P = np.empty((N, nv, nv))
    if m == 0:
        P[:] = np.eye(nv)
        return P
    kernel = native.contact_projector() if method == "cholesky" else None
    if method == "svd":
        slow = np.arange(N)
    elif kernel is not None:  # the same computation in C++ (native_contact.cpp)
        J = np.ascontiguousarray(Jc)
        ok = np.empty(N, np.uint8)
        kernel(N, m, nv, J.ctypes.data, float(rcond), FAST_CONDITION, P.ctypes.data, ok.ctypes.data)
        slow = np.flatnonzero(ok == 0)
    else:
        step = max(32, _CHUNK_DOUBLES // (m * nv + nv * nv + m * m))
        slow = [a + np.flatnonzero(~_normal_projector(Jc[a : a + step], rcond, P[a : a + step]))
                for a in range(0, N, step)]
        slow = np.concatenate(slow) if slow else np.zeros(0, int)
    if len(slow):
        P[slow] = _svd_projector(Jc[slow], rcond)
    return P


def _svd_projector(J: np.ndarray, rcond: float) -> np.ndarray:
    """I − V_r V_rᵀ with pinv's cut-off; NaN for samples with non-finite entries."""
    nv = J.shape[2]
    finite = np.isfinite(J).all(axis=(1, 2))
    P = np.full((len(J), nv, nv), np.nan)
    if finite.any():
        _, s, Vt = np.linalg.svd(J[finite], full_matrices=False)
        smax = s[:, :1]
        Vr = Vt * ((s > rcond * smax) & (smax > 0))[:, :, None]
        P[finite] = np.eye(nv) - np.matmul(Vr.transpose(0, 2, 1), Vr)
    return P


def _lower_inverse(L: np.ndarray) -> np.ndarray:
    """L⁻¹ for lower-triangular L (N, m, m): row j of L⁻¹ = (e_j − Σ_{k<j} L_jk row_k)/L_jj, each
    step one vector operation over all samples (samples last, contiguous)."""
    n, m, _ = L.shape
    Lt = np.ascontiguousarray(L.transpose(1, 2, 0))
    R = np.zeros((m, m, n))
    d = np.arange(m)
    R[d, d] = 1.0 / Lt[d, d]
    for j in range(1, m):  # R[j] = (e_j − Σ_k L_jk R[k]) / L_jj: right-looking, column k = j − 1
        R[j:, :j] -= Lt[j:, j - 1, None, :] * R[j - 1, None, :j]
        R[j, :j] *= R[j, j]
    return R.transpose(2, 0, 1)


def _normal_projector(J: np.ndarray, rcond: float, out: np.ndarray, damped: bool = False) -> np.ndarray:
    """P = I − Jᵀ G⁻¹ J into ``out`` for one chunk; returns the samples certified (see
    :func:`null_space_projector`), the others to be redone by the SVD."""
    n, m, nv = J.shape
    G = np.matmul(J, J.transpose(0, 2, 1))
    d = np.arange(m)
    g = G[:, d, d]
    s2 = g.sum(axis=1)  # ‖J‖²_F
    scale2 = np.where(s2 > 0, s2, 1.0)
    G[:, d, d] = np.where(g > 0, g, scale2[:, None])  # zero rows: a unit pivot at the sample's scale
    if damped:  # certify on G + δI (positive definite), then refactor the certified samples undamped
        G[:, d, d] += (16 * m * np.finfo(float).eps) * scale2[:, None]
    try:
        L = np.linalg.cholesky(G)
    except np.linalg.LinAlgError:  # a singular G in the chunk (dependent rows)
        if damped:
            return np.zeros(n, bool)
        ok = np.zeros(n, bool)
        with np.errstate(all="ignore"):
            cert = _normal_projector(J, rcond, np.empty_like(out), damped=True)
        if cert.any():
            sub = np.empty((int(cert.sum()), nv, nv))
            ok[cert] = _normal_projector(J[cert], rcond, sub)
            out[cert] = sub
        return ok
    Li = _lower_inverse(L)
    k2 = s2 * np.einsum("nij,nij->n", Li, Li)  # (‖J‖_F ‖L⁻¹‖_F)² ≥ κ²
    ok = (k2 <= FAST_CONDITION**2) & (k2 * rcond**2 < 1.0)
    X = np.matmul(Li, J)
    np.matmul(X.transpose(0, 2, 1), X, out=out)
    np.negative(out, out=out)
    out[:, np.arange(nv), np.arange(nv)] += 1.0
    return ok


def null_space_basis(Jc: np.ndarray, rcond: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal bases B (N, nv, nv − m) of null(Jc) for Jc (N, m, nv), and where they equal the projector.

    Householder QR of Jcᵀ = Q R (LAPACK, batched over samples): B is the last nv − m columns of Q,
    so Jc B = 0, BᵀB = I and B Bᵀ = I − Jc⁺Jc for Jc of full row rank. ``exact`` (N,) marks the
    samples where B Bᵀ also equals :func:`null_space_projector` (pinv keeps every row), with a margin:
    σ_min(Jc) ≥ 1/‖R⁻¹‖_F ≥ 1e4·rcond·‖Jc‖_F. Elsewhere (dependent or nearly dependent rows,
    m ≥ nv) B may span only part of the null space: use the projector there.
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

"""Contact maps: floating-base identification without force sensing.

Whole-body dynamics with contact wrenches f at contact frames:

    M(q) v̇ + h(q, v) = Sᵀ τ + Jcᵀ f,        Jc = stacked contact Jacobians.

With P = I − Jc⁺ Jc (the orthogonal projector onto null(Jc)), P Jcᵀ = 0, so the
unknown f disappears:

    P [Y(q, v, v̇) π + Sᵀ Φ(v, v̇) φ] = P Sᵀ τ,

linear in the inertial parameters π and joint terms φ (friction, armature, offset).
P is computed batched (see :func:`null_space_projector`), per contact pattern on the
active contacts' rows only; rank-deficient stances (e.g. dependent foot rows) are handled
without a per-sample pinv. A sample with no contact (flight) has P = I: the full
floating-base equations.

With measured contact wrenches (force plates, foot F/T) the wrench moves to the known
side instead: Y π + Sᵀ Φ φ = Sᵀ τ + Jcᵀ f (``mode="wrench"``).

Jacobians are Pinocchio ``getFrameJacobian`` in LOCAL_WORLD_ALIGNED; point contacts use
the 3 linear rows, 6-D (flat-foot) contacts all 6. Measured forces are given in the same
frame: (N, n_contacts, 3) for point, (N, n_contacts, 6) [f; τ] for 6-D contacts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Sequence

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError
from .compress import NormalEquations
from .terms import ModelStructure, _in_robot_order

__all__ = ["ContactStructure", "contact_jacobians", "null_space_projector", "detect_contacts"]


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
    for j in range(m):  # column-wise Cholesky and forward substitution, vectorised over N
        Lj = L[:, j, :j]
        ljj = np.sqrt(np.maximum(G[:, j, j] + eps - np.einsum("nk,nk->n", Lj, Lj), eps))
        L[:, j, j] = ljj
        if j + 1 < m:
            L[:, j + 1 :, j] = (G[:, j + 1 :, j] - np.einsum("nik,nk->ni", L[:, j + 1 :, :j], Lj)) / ljj[:, None]
        X[:, j] = (Jc[:, j] - np.einsum("nk,nkc->nc", Lj, X[:, :j])) / ljj[:, None]
    P = -np.matmul(X.transpose(0, 2, 1), X)
    P[:, np.arange(nv), np.arange(nv)] += 1.0
    return P


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
    velocity is below ``speed``. Needs the base pose and twist (``base_q``, ``base_v``).
    """
    if traj.base_q is None or traj.base_v is None:
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


@dataclass
class ContactStructure(ModelStructure):
    """A floating-base :class:`ModelStructure` whose rows are mapped by the contacts.

    ``mode="projected"``: rows P W, target P Sᵀ τ (no force sensing).
    ``mode="wrench"``: rows W, target Sᵀ τ + Jcᵀ f (measured wrenches in
    ``traj.extras["contact_forces"]``).
    Contact flags come from ``traj.extras[contact_key]`` (N, n_contacts) or, when absent,
    from :func:`detect_contacts`. ``contact_offset`` is the radius of spherical feet: point
    contacts are taken that far below the foot frame (world z), where the ground touches.
    """

    contact_frames: tuple[str, ...] = ()
    contact_dims: tuple[int, ...] = ()
    mode: Literal["projected", "wrench"] = "projected"
    contact_key: str = "contact"
    rcond: float = 1e-7
    contact_offset: float = 0.0
    _fids: list[int] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        self.rows = "all"
        super().__post_init__()
        if not self.robot.floating_base:
            raise RobotModelError(f"{self.robot.name}: contact projection needs a floating-base robot")
        if not self.contact_frames:
            raise RobotModelError("no contact frames given")
        self.contact_frames = tuple(self.contact_frames)
        self.contact_dims = tuple(self.contact_dims) or (3,) * len(self.contact_frames)
        if len(self.contact_dims) != len(self.contact_frames) or any(d not in (3, 6) for d in self.contact_dims):
            raise RobotModelError("contact_dims must give 3 (point) or 6 (flat foot) per contact frame")
        if self.mode not in ("projected", "wrench"):
            raise RobotModelError(f"unknown contact mode '{self.mode}'; use 'projected' or 'wrench'")
        self._fids = [self.robot.frame_id(f) for f in self.contact_frames]

    # ---- contacts -------------------------------------------------------------------
    def contacts(self, traj: Trajectory) -> np.ndarray:
        flags = traj.extras.get(self.contact_key)
        if flags is None:
            return detect_contacts(self.robot, traj, self.contact_frames)
        flags = np.asarray(flags, dtype=bool)
        if flags.shape != (len(traj), len(self.contact_frames)):
            raise DataError(
                f"contact flags '{self.contact_key}' have shape {flags.shape}, expected "
                f"({len(traj)}, {len(self.contact_frames)}) for frames {list(self.contact_frames)}",
                traj.source,
            )
        return flags

    def jacobians(self, Q: np.ndarray, flags: np.ndarray) -> np.ndarray:
        return contact_jacobians(self.robot, self._fids, self.contact_dims, Q, flags, self.contact_offset)

    def projector(self, Q: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """P (N, nv, nv), computed per contact pattern on the active rows only."""
        N = Q.shape[0]
        P = np.empty((N, self.robot.nv, self.robot.nv))
        patterns, inverse = np.unique(flags, axis=0, return_inverse=True)
        for k, pattern in enumerate(patterns):
            idx = np.flatnonzero(inverse.ravel() == k)
            on = np.flatnonzero(pattern)
            fids = [self._fids[i] for i in on]
            dims = [self.contact_dims[i] for i in on]
            J = contact_jacobians(self.robot, fids, dims, Q[idx], np.ones((len(idx), len(on)), bool), self.contact_offset)
            P[idx] = null_space_projector(J, self.rcond)
        return P

    # ---- the mapped equations -------------------------------------------------------------
    def _mapped(self, traj: Trajectory, with_regressor: bool = True):
        Q, V, A = self.state(traj)
        y = super().target(traj)  # Sᵀ τ, (N, nv)
        flags = self.contacts(traj)
        W = ModelStructure.evaluate(self, Q, V, A) if with_regressor else None
        if self.mode == "projected":
            P = self.projector(Q, flags)
            y = np.einsum("nij,nj->ni", P, y)
            if W is not None:
                W = np.matmul(P, W)
        else:
            f = traj.extras.get("contact_forces")
            if f is None:
                raise DataError("mode 'wrench' needs measured forces in extras['contact_forces']", traj.source)
            f = np.asarray(f, dtype=float).reshape(len(traj), -1)
            Jc = self.jacobians(Q, flags)
            if f.shape[1] != Jc.shape[1]:
                raise DataError(
                    f"contact_forces have {f.shape[1]} values per sample, expected {Jc.shape[1]} "
                    f"({list(self.contact_dims)} for {list(self.contact_frames)})",
                    traj.source,
                )
            y = y + np.einsum("nmi,nm->ni", Jc, f)
        return W, y

    def target(self, traj: Trajectory) -> np.ndarray:
        """P Sᵀ τ (projected) or Sᵀ τ + Jcᵀ f (wrench), shape (N, nv)."""
        return self._mapped(traj, with_regressor=False)[1]

    def fold(self, ne: NormalEquations, traj: Trajectory) -> None:
        """Add one chunk to the normal equations (used by :func:`compress`)."""
        W, y = self._mapped(traj)
        ne.add(W, y)

    def torques(self, params: np.ndarray, traj: Trajectory, chunk: int = 4096) -> np.ndarray:
        """Predicted mapped effort: P W π (projected) or W π (wrench), shape (N, nv)."""
        out = np.empty((len(traj), self.n_rows))
        for s in range(0, len(traj), chunk):
            part = traj.take(slice(s, s + chunk))
            W, _ = self._mapped(part)
            out[s : s + len(part)] = W @ params
        return out

    def project(self, traj: Trajectory, tau: np.ndarray) -> np.ndarray:
        """Map actuated torques (N, n_actuated) of any model (e.g. a black-box MLP) to P Sᵀ τ."""
        ordered = _in_robot_order(self.robot, traj)
        Q = self.robot.full_configuration(ordered.q, ordered.base_q)
        full = np.zeros((len(traj), self.robot.nv))
        full[:, self.robot.actuated_v_indices] = tau
        if self.mode == "projected":
            return np.einsum("nij,nj->ni", self.projector(Q, self.contacts(traj)), full)
        return full

    def settings(self) -> dict:
        return {
            **super().settings(),
            "contact_frames": list(self.contact_frames),
            "contact_dims": list(self.contact_dims),
            "contact_mode": self.mode,
            "rcond": self.rcond,
            "contact_offset": self.contact_offset,
        }

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

Every unactuated coordinate keeps its row with the known generalized force 0: the 6 rows of a
floating base, and the rows of passive joints (no actuator, ``Robot.passive_joints``; e.g. a leg
on a vertical rail, a fixed-base model whose rail is the unactuated "base"). The projected
equations use all nv rows, with Sᵀτ zero on those rows; a passive joint's own friction terms
are columns on its row like an actuated joint's.

Compression folds the projected equations through an orthonormal null-space basis B
(nv × k, k = nv − rank Jc: 6 for four point feet on Solo12, 12 for two), since P = B Bᵀ gives
Σ Wᵀ P W = Σ (BᵀW)ᵀ(BᵀW): k rows per sample instead of nv (see :func:`null_space_basis`,
``fold_basis``). The k rows are combinations of joints, so the rows are pooled
(:meth:`~.normal_equations.NormalEquations.add_pooled`); ``fold_basis="projector"`` keeps the nv
projected rows apart (per-row weights and residuals) at 2–3× the cost.

With measured contact wrenches (force plates, foot F/T) the wrench moves to the known
side instead: Y π + Sᵀ Φ φ = Sᵀ τ + Jcᵀ f (``mode="wrench"``).

Measured wrenches without joint torques (``contact_rows="base"``): the 6 floating-base
rows alone, Y_base π = [Jcᵀ f]_base, since Sᵀ τ vanishes there. They carry every
identifiable inertial parameter of the tree (the base-link equations of a floating
base), in particular the total mass and the CoM; the joint terms φ are not seen.

A constant measurement bias b of the wrenches (F/T offsets of tens of N) adds known
columns: f_meas = f + b, so Y π + Jcᵀ E b = Sᵀ τ + Jcᵀ f_meas with E placing b
(``wrench_offset``): ``"foot"`` a force per foot in world axes, ``"sole"`` a force per
foot in the foot (sole) frame, E_k = R_k (rotating with the foot), ``"net"`` one world
force shared equally by the active contacts. Only force components are modelled, those
in ``offset_axes`` (default "xy": a vertical bias is confounded with m·g on standing data).

Jacobians are Pinocchio ``getFrameJacobian`` in LOCAL_WORLD_ALIGNED; point contacts use
the 3 linear rows, 6-D (flat-foot) contacts all 6. Measured forces are given in the same
frame: (N, n_contacts, 3) for point, (N, n_contacts, 6) [f; τ] for 6-D contacts.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Iterable, Literal

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError, setting
from .normal_equations import NormalEquations
from .contact_inference import infer_contacts, normal_forces
from .contact_kinematics import contact_jacobians, contact_rotations, detect_contacts, null_space_basis, null_space_projector
from .rowmap import ContactNullSpace, RowMap
from .terms import ModelStructure, in_robot_order

__all__ = [
    "ContactStructure",
    "choose_contact_rows",
    "WRENCH_OFFSETS",
]

#: Constant contact-wrench bias models (see the module docstring).
WRENCH_OFFSETS = ("none", "net", "foot", "sole")
_AXES = "xyz"
_BASE_ROWS = 6


def _has_torques(traj: Trajectory) -> bool:
    return traj.tau is not None and bool(np.any(np.asarray(traj.tau) != 0.0))


def choose_contact_rows(trajectories: Trajectory | Iterable[Trajectory]) -> tuple[str, str]:
    """``("base", why)`` when no log has a non-zero joint torque, else ``("all", why)``.

    With measured wrenches and no torques only the 6 floating-base rows carry information;
    fitting the joint rows would fit the inertial parameters to a zero target.
    """
    trajs = [trajectories] if isinstance(trajectories, Trajectory) else list(trajectories)
    without = [t.source for t in trajs if not _has_torques(t)]
    if len(without) == len(trajs):
        return "base", ("no joint torques in the log(s) (missing or all zero): fitting the 6 floating-base rows "
                        "only (mass, CoM and the other base-identifiable parameters; no joint friction)")
    if without:
        raise DataError(
            f"some logs have joint torques and some have none ({without}); use {setting('contact_rows', 'base')} "
            "to ignore the torques, or give torques for every log"
        )
    return "all", "joint torques present: fitting the floating-base rows and the joint torque rows"


@dataclass
class ContactStructure(ModelStructure):
    """A :class:`ModelStructure` on all nv rows (a floating base, or a fixed base with passive
    joints, module docstring) whose rows are mapped by the contacts.

    ``mode="projected"``: rows P W, target P Sᵀ τ (no force sensing).
    ``mode="wrench"``: rows W, target Sᵀ τ + Jcᵀ f (measured wrenches in
    ``traj.extras["contact_forces"]``, (N, n_contacts, 3|6) or flattened).
    ``contact_rows``: ``"all"`` the nv rows; ``"base"`` the 6 floating-base rows only
    (wrench mode, logs without joint torques); ``"auto"`` is "all" here — resolve it from
    the data with :func:`choose_contact_rows` (the CLI does). Rows are compressed separately,
    so ``identify(..., method="wls")`` gives base and torque rows their own weights.
    ``wrench_offset`` / ``offset_axes``: constant wrench bias parameters (module docstring),
    labelled ``bias.<frame|net>.f<axis>`` after the joint terms.
    Contact flags come from ``traj.extras[contact_key]`` (N, n_contacts) or, when absent, from
    the measured normal forces (wrench mode, :func:`~.contact_inference.infer_contacts`) or
    :func:`detect_contacts` (projected mode). ``contact_offset`` is the radius of spherical feet: point
    contacts are taken that far below the foot frame (world z), where the ground touches.
    ``fold_basis`` (projected mode): ``"nullspace"`` folds k = nv − rank Jc pooled rows per sample
    (module docstring), ``"projector"`` the nv projected rows kept apart (each row weighted by its own
    residual σ); ``"auto"``: the projector when the robot has passive joints (their rows hold no torque
    noise and may be in other units, N on a rail: pooled with the torque rows, one weight misweights
    them and the acceleration noise in the regressor shrinks the masses), else the null-space basis.
    """

    contact_frames: tuple[str, ...] = ()
    contact_dims: tuple[int, ...] = ()
    mode: Literal["projected", "wrench"] = "projected"
    contact_key: str = "contact"
    rcond: float = 1e-7
    contact_offset: float = 0.0
    contact_rows: Literal["auto", "base", "all"] = "auto"
    wrench_offset: Literal["none", "net", "foot", "sole"] = "none"
    offset_axes: str = "xy"
    fold_basis: Literal["auto", "nullspace", "projector"] = "auto"
    _fids: list[int] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        if not self.robot.floating_base and self.contact_rows == "base":
            raise RobotModelError(
                f"{self.robot.name}: {setting('contact_rows', 'base')} fits the 6 floating-base rows, but the robot "
                f"has a fixed base; load it with {setting('floating_base', True)}")
        self.rows = "all"
        super().__post_init__()
        if not self.contact_frames:
            raise RobotModelError("no contact frames given")
        self.contact_frames = tuple(self.contact_frames)
        self.contact_dims = tuple(self.contact_dims) or (3,) * len(self.contact_frames)
        if len(self.contact_dims) != len(self.contact_frames) or any(d not in (3, 6) for d in self.contact_dims):
            raise RobotModelError("contact_dims must give 3 (point) or 6 (flat foot) per contact frame")
        if self.mode not in ("projected", "wrench"):
            raise RobotModelError(f"unknown contact mode '{self.mode}'; use 'projected' or 'wrench'")
        if self.contact_rows not in ("auto", "base", "all"):
            raise RobotModelError(f"unknown contact_rows '{self.contact_rows}'; use 'auto', 'base' or 'all'")
        if self.fold_basis not in ("auto", "nullspace", "projector"):
            raise RobotModelError(f"unknown fold_basis '{self.fold_basis}'; use 'auto', 'nullspace' or 'projector'")
        if self.fold_basis == "auto":  # passive rows: no torque noise, their own unit (N on a rail): own weights
            self.fold_basis = "projector" if self.robot.passive_joints else "nullspace"
        if self.wrench_offset not in WRENCH_OFFSETS:
            raise RobotModelError(f"unknown wrench_offset '{self.wrench_offset}'; choose from {WRENCH_OFFSETS}")
        if self.mode == "projected" and (self.contact_rows == "base" or self.wrench_offset != "none"):
            raise RobotModelError(f"{setting('contact_rows', 'base')} and {setting('wrench_offset')} need measured "
                                  f"wrenches ({setting('mode', 'wrench')})")
        axes = "".join(a for a in _AXES if a in self.offset_axes)
        if not axes or set(self.offset_axes) - set(_AXES):
            raise RobotModelError(f"offset_axes must be a non-empty subset of 'xyz', got '{self.offset_axes}'")
        self.offset_axes = axes
        self._fids = [self.robot.frame_id(f) for f in self.contact_frames]
        if self.contact_rows == "base":
            self._row_idx = np.arange(_BASE_ROWS)
            self._act_row = np.zeros(0, dtype=int)
        owners = {"none": [], "net": ["net"], "foot": list(self.contact_frames), "sole": list(self.contact_frames)}
        self._offset_owners = owners[self.wrench_offset]
        self.labels = self.labels + [f"bias.{o}.f{a}" for o in self._offset_owners for a in self.offset_axes]

    # ---- sizes ----------------------------------------------------------------------
    @property
    def row_map(self) -> RowMap:
        """P(q) = I − Jc⁺Jc per sample (projected), or the kept rows (wrench): :class:`~.rowmap.ContactNullSpace`."""
        return ContactNullSpace(self)

    @property
    def base_rows_only(self) -> bool:
        return self.contact_rows == "base"

    @property
    def n_offset_params(self) -> int:
        return len(self._offset_owners) * len(self.offset_axes)

    @property
    def n_params(self) -> int:
        return super().n_params + self.n_offset_params

    @property
    def row_names(self) -> list[str]:
        names = super().row_names
        return names[:_BASE_ROWS] if self.base_rows_only else names

    def offset_values(self, params: np.ndarray) -> dict[str, dict[str, float]]:
        """Identified bias per owner (frame or "net"): {"fx": …, "fy": …} [N]."""
        vals = np.asarray(params)[super().n_params :]
        na = len(self.offset_axes)
        return {o: {f"f{a}": float(vals[k * na + j]) for j, a in enumerate(self.offset_axes)}
                for k, o in enumerate(self._offset_owners)}

    def force_bias(self, params: np.ndarray, Q: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """The identified bias as wrenches (N, n_contacts, 6) in world axes, the part to subtract
        from the measured ones ("net" is split equally over the active contacts, as in the model)."""
        n_c = len(self.contact_frames)
        N = Q.shape[0]
        out = np.zeros((N, n_c, 6))
        if self.wrench_offset == "none":
            return out
        vals = np.asarray(params)[super().n_params :].reshape(len(self._offset_owners), -1)
        ax = [_AXES.index(a) for a in self.offset_axes]
        if self.wrench_offset == "net":
            share = flags / np.maximum(flags.sum(axis=1, keepdims=True), 1)
            out[:, :, ax] = share[:, :, None] * vals[0]
        elif self.wrench_offset == "foot":
            out[:, :, ax] = vals
        else:
            R = contact_rotations(self.robot, self._fids, Q)
            out[:, :, :3] = np.einsum("nkij,kj->nki", R[:, :, :, ax], vals)
        return out * flags[:, :, None]

    # ---- contacts -------------------------------------------------------------------
    def contacts(self, traj: Trajectory) -> np.ndarray:
        flags = traj.extras.get(self.contact_key)
        if flags is None and self.mode == "wrench" and traj.extras.get("contact_forces") is not None:
            # measured wrenches: a foot is in contact where its normal force stands out of the noise
            return infer_contacts(normal_forces(self.measured_wrenches(traj), self.contact_dims))[0]
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

    def measured_wrenches(self, traj: Trajectory) -> np.ndarray:
        """``extras["contact_forces"]`` as (N, Σ dims), checked against the contact frames."""
        f = traj.extras.get("contact_forces")
        if f is None:
            raise DataError("mode 'wrench' needs measured forces in extras['contact_forces']", traj.source)
        f = np.asarray(f, dtype=float)
        m, n_c = int(sum(self.contact_dims)), len(self.contact_frames)
        per_contact = f.ndim == 3 and f.shape[:2] == (len(traj), n_c) and set(self.contact_dims) == {f.shape[2]}
        flat = f.ndim == 2 and f.shape == (len(traj), m)
        if not (per_contact or flat):
            raise DataError(
                f"contact_forces have shape {f.shape}, expected ({len(traj)}, {n_c}, d) or ({len(traj)}, {m}) "
                f"with d per contact {list(self.contact_dims)} for frames {list(self.contact_frames)}",
                traj.source,
            )
        return f.reshape(len(traj), m)

    # ---- the mapped equations -------------------------------------------------------------
    def _offset_columns(self, Q: np.ndarray, Jc: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """Bias columns Jcᵀ E (N, nv, n_offset) for the active contacts (Jc rows of inactive ones are 0)."""
        N = Q.shape[0]
        out = np.zeros((N, self.robot.nv, self.n_offset_params))
        if not self.n_offset_params:
            return out
        starts = np.concatenate([[0], np.cumsum(self.contact_dims)])[:-1]
        ax = [_AXES.index(a) for a in self.offset_axes]
        na = len(ax)
        if self.wrench_offset == "net":
            n_on = np.maximum(flags.sum(axis=1), 1)[:, None]
            for k, s0 in enumerate(starts):
                out += Jc[:, s0 + np.array(ax), :].transpose(0, 2, 1) / n_on[:, :, None]
        elif self.wrench_offset == "foot":
            for k, s0 in enumerate(starts):
                out[:, :, k * na : (k + 1) * na] = Jc[:, s0 + np.array(ax), :].transpose(0, 2, 1)
        else:  # sole: f_world = R_k b_k
            R = contact_rotations(self.robot, self._fids, Q)
            for k, s0 in enumerate(starts):
                out[:, :, k * na : (k + 1) * na] = np.einsum("nji,njc->nic", Jc[:, s0 : s0 + 3, :], R[:, k][:, :, ax])
        return out

    def evaluate(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Unmapped regressor (N, n_rows, n_params), bias columns with every contact active
        (the structural regressor, e.g. for base parameters)."""
        W = ModelStructure.evaluate(self, Q, V, A)
        if self.n_offset_params:
            flags = np.ones((Q.shape[0], len(self._fids)), bool)
            W[:, :, super().n_params :] = self._offset_columns(Q, self.jacobians(Q, flags), flags)[:, self._row_idx]
        return W

    def _joint_target(self, traj: Trajectory) -> np.ndarray:
        """Sᵀ τ on all nv rows; a typed error (naming the fix) when torques are missing or all zero."""
        hint = (f"use {setting('contact_rows', 'base')} to fit the 6 floating-base rows to the "
                "measured wrenches only" if self.mode == "wrench" else
                "projected contact identification needs joint torques; with measured contact wrenches use "
                f"{setting('mode', 'wrench')}")
        if traj.tau is None:
            raise DataError(f"the log has no joint torques ('tau'); {hint}", traj.source)
        y = super().target(traj)
        if not np.any(y):
            raise DataError(
                f"every joint torque is zero in samples {traj.t[0]:.3f}..{traj.t[-1]:.3f} s: the joint rows would "
                f"fit the inertial parameters to a zero target; {hint}", traj.source)
        return y

    def _mapped(self, traj: Trajectory, with_regressor: bool = True):
        Q, V, A = self.state(traj)
        flags = self.contacts(traj)
        W = ModelStructure.evaluate(self, Q, V, A) if with_regressor else None
        if self.mode == "projected":
            P = self.projector(Q, flags)
            y = np.einsum("nij,nj->ni", P, self._joint_target(traj))
            if W is not None:
                W = np.matmul(P, W)
            return W, y
        f = self.measured_wrenches(traj)
        Jc = self.jacobians(Q, flags)
        if flags.any() and not np.any(f[np.repeat(flags, self.contact_dims, axis=1)]):
            warnings.warn(f"{traj.source}: contact_forces are all zero while feet are in contact "
                          f"(samples {traj.t[0]:.3f}..{traj.t[-1]:.3f} s)", RuntimeWarning, stacklevel=3)
        rows = self._row_idx
        y = np.einsum("nmi,nm->ni", Jc[:, :, rows], f)
        if not self.base_rows_only:
            y = y + self._joint_target(traj)
        if W is not None and self.n_offset_params:
            W[:, :, super().n_params :] = self._offset_columns(Q, Jc, flags)[:, rows]
        return W, y

    def target(self, traj: Trajectory) -> np.ndarray:
        """P Sᵀ τ (projected) or Sᵀ τ + Jcᵀ f (wrench) on the kept rows, shape (N, n_rows)."""
        return self._mapped(traj, with_regressor=False)[1]

    def fold(self, ne: NormalEquations, traj: Trajectory) -> None:
        """Add one chunk to the normal equations (used by :func:`compress`).

        Projected mode with ``fold_basis="nullspace"``: per contact pattern, Z = BᵀW and z = BᵀSᵀτ
        (B from :func:`null_space_basis`) are folded pooled, ZᵀZ by one SYRK; samples where B is not
        exact fold P W and P Sᵀτ instead. Either way the summed normal equations are those of the
        projected rows, Σ WᵀPW and Σ WᵀP Sᵀτ; the range statistics are those of P Sᵀτ.
        """
        if self.mode != "projected" or self.fold_basis == "projector":
            W, y = self._mapped(traj)
            ne.add(W, y)
            return
        Q, V, A = self.state(traj)
        flags = self.contacts(traj)
        y = self._joint_target(traj)
        p = self.n_params
        patterns, inverse = np.unique(flags, axis=0, return_inverse=True)
        for k, pattern in enumerate(patterns):
            idx = np.flatnonzero(inverse.ravel() == k)
            on = np.flatnonzero(pattern)
            J = contact_jacobians(self.robot, [self._fids[i] for i in on], [self.contact_dims[i] for i in on],
                                  Q[idx], np.ones((len(idx), len(on)), bool), self.contact_offset)
            B, exact = null_space_basis(J, self.rcond)
            for sel, basis in ((exact, True), (~exact, False)):
                if not sel.any():
                    continue
                rows = idx if sel.all() else idx[sel]
                W = ModelStructure.evaluate(self, Q[rows], V[rows], A[rows])  # (n, nv, p), this group only
                if basis:
                    Bt = (B if sel.all() else B[sel]).transpose(0, 2, 1)
                    z = np.matmul(Bt, y[rows][:, :, None])[:, :, 0]
                    ne.add_pooled(np.matmul(Bt, W).reshape(-1, p), z.ravel(), np.matmul(Bt.transpose(0, 2, 1), z[:, :, None])[:, :, 0])
                else:  # dependent or nearly dependent contact rows: the projector
                    P = null_space_projector(J[sel], self.rcond)
                    Py = np.matmul(P, y[rows][:, :, None])[:, :, 0]
                    ne.add_pooled(np.matmul(P, W).reshape(-1, p), Py.ravel(), Py)

    def torques(self, params: np.ndarray, traj: Trajectory, chunk: int = 4096) -> np.ndarray:
        """Predicted mapped effort: P W π (projected) or W π (wrench), shape (N, n_rows)."""
        out = np.empty((len(traj), self.n_rows))
        for s in range(0, len(traj), chunk):
            part = traj.take(slice(s, s + chunk))
            Q, V, A = self.state(part)
            W = ModelStructure.evaluate(self, Q, V, A)
            if self.mode == "projected":
                W = self.row_map.apply(W, Q, self.contacts(part))
            elif self.n_offset_params:
                flags = self.contacts(part)
                W[:, :, super().n_params :] = self._offset_columns(Q, self.jacobians(Q, flags), flags)[:, self._row_idx]
            out[s : s + len(part)] = W @ params
        return out

    def project(self, traj: Trajectory, tau: np.ndarray) -> np.ndarray:
        """Map actuated torques (N, n_actuated) of any model (e.g. a black-box MLP) to P Sᵀ τ."""
        ordered = in_robot_order(self.robot, traj)
        Q = self.robot.full_configuration(ordered.q, ordered.base_q)
        full = np.zeros((len(traj), self.robot.nv))
        full[:, self.robot.actuated_v_indices] = tau
        if self.mode == "projected":
            return np.einsum("nij,nj->ni", self.projector(Q, self.contacts(traj)), full)
        return full[:, self._row_idx]

    def settings(self) -> dict:
        return {
            **super().settings(),
            "contact_frames": list(self.contact_frames),
            "contact_dims": list(self.contact_dims),
            "contact_mode": self.mode,
            "rcond": self.rcond,
            "contact_offset": self.contact_offset,
            "contact_rows": "base" if self.base_rows_only else "all",
            "wrench_offset": self.wrench_offset,
            "offset_axes": self.offset_axes,
            "fold_basis": self.fold_basis,
        }

    @classmethod
    def from_settings(cls, robot, settings: dict, **common) -> "ContactStructure":
        """Rebuild from :meth:`settings` (e.g. ``result.json``'s ``settings``)."""
        return cls(
            robot, **common, contact_frames=tuple(settings["contact_frames"]),
            contact_dims=tuple(settings.get("contact_dims", ())), mode=settings.get("contact_mode", "projected"),
            rcond=settings.get("rcond", 1e-7), contact_offset=settings.get("contact_offset", 0.0),
            contact_rows=settings.get("contact_rows", "all"), wrench_offset=settings.get("wrench_offset", "none"),
            offset_axes=settings.get("offset_axes", "xy"), fold_basis=settings.get("fold_basis", "nullspace"),
        )

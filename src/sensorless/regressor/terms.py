"""Regressor terms: the linear map from parameters to joint torques.

Inverse dynamics with per-joint friction and rotor inertia is linear in the parameters:

    τ_j = [Y(q, v, v̇) π]_j + fv_j v_j + fc_j sgn(v_j) + o_j + Ia_j v̇_j

* ``Y`` is Pinocchio's joint-torque regressor (``computeJointTorqueRegressor``), with
  π the stacked body parameters (10 per body, see :mod:`sensorless.parameters`).
* Joint terms, per *term joint* (the actuated joints, then the passive ones,
  :attr:`~sensorless.robot.Actuation.term_joints`) and in this order when enabled: viscous ``fv``,
  Coulomb ``fc``, Stribeck ``stribeck`` (parameter fs − fc), constant ``offset``, ``armature``
  (reflected rotor inertia) and, opt-in, ``presliding`` (the state s_c of :mod:`.friction_state`
  along each log from 0, :meth:`ModelStructure.friction_states`). The friction columns, the rest velocity and the equations left out
  of the fit (at rest, at a velocity reversal) are :mod:`.friction_columns`.

* A passive joint (no actuator, generalized force 0) has only the friction terms
  (:data:`~.joint_spec.PASSIVE_TERMS`: fv, fc, stribeck): no offset (no torque sensor) and no
  armature (no rotor). Its equation is kept, with the known target 0.

* Terms may differ per joint (``joint_terms={"j1": ("fv",), "*": ("fv", "fc")}``). The
  column block of every joint still holds the union of the terms (same layout for all
  joints); a term a joint does not have is a zero column, so its parameter is fixed at 0
  (it is not a base parameter) and :meth:`ModelStructure.terms_of` lists the real ones.

* Drive terms (``drives``, :class:`~.drive_terms.DriveTerm`; empty here, a transmission's
  friction, motor inertia and springs): a column g_d f_{d,p}(θ, θ̇, θ̈) on every kept row,
  one parameter coupling several rows.

The full parameter vector is ``[π (10 · n_bodies), drive terms, terms of joint 1, terms of
joint 2, …]``; π and the drive terms are the *block* columns (:meth:`ModelStructure.block_regressor`),
folded densely, the joint terms sit on their joint's row only.
Which rows of the equation are used (the "row map", :mod:`.rowmap`) is chosen by ``rows``:
``"actuated"`` keeps the rows whose generalized force is known, the actuated joints' (measured)
then the passive joints' (zero) (fixed-base arms), ``"all"`` keeps all
nv rows with τ_full = Sᵀ τ (a floating base in flight; contact maps come with the
contact module, coupling matrices with the transmission module). The structure's arrays
(Q, V, A) are mapped to Pinocchio's by :meth:`ModelStructure.pinocchio_state` (the
identity here; q = Gθ + q₀ for a transmission).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Mapping

import numpy as np
import pinocchio as pin

from ..data.gains import no_effort_message
from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError
from ..parameters import PARAMETER_NAMES
from ..robot import Robot
from .friction_columns import coulomb_sign, fit_keep, sliding_sign
from .friction_state import presliding_states
from .joint_spec import (DEFAULT_STRIBECK_VELOCITY, per_joint_values, named_joints, parse_joint_terms, parse_presliding,
                         passive_terms)
from .joint_terms import JOINT_TERMS, TermInputs, joint_term
from .joint_terms.stribeck import FRICTION_LAWS
from .rowmap import ActuatedRows, RowMap
from .native import native_regressor
from .native import threads as native_threads

__all__ = ["ModelStructure"]

@dataclass
class ModelStructure:
    """Which columns and rows make up the identification model of a robot.

    ``joint_terms``: a tuple (the same terms on every actuated joint), or a per-joint
    mapping / spec string (:func:`parse_joint_terms`); afterwards ``joint_terms`` is the
    union and ``per_joint_terms`` the mapping. ``coulomb_smoothing``: the transition width ε
    for every joint, or ``{joint: ε}`` (0 = sgn). ``stribeck_velocity``: vs per joint with a
    ``stribeck`` term. ``friction_law``: the Stribeck column (module docstring).
    """

    robot: Robot
    joint_terms: tuple[str, ...] = ("fv", "fc", "offset", "armature")
    coulomb_smoothing: float = 0.0
    rows: Literal["actuated", "all"] | None = None
    per_joint_terms: dict | None = None
    stribeck_velocity: dict | None = None
    rest_velocity: dict | None = None
    friction_law: str = "blend"
    presliding: dict | None = None  #: {joint: {"k": 1/presliding distance [1/rad], "play": h [rad]}}
    labels: list[str] = field(init=False)
    #: drive terms (coupled columns, module docstring); set by :class:`~.transmission.TransmissionStructure`
    drives = ()  # not a dataclass field
    #: Pinocchio regressor columns of the identified bodies (None: every body)
    _body_cols = None
    #: the row map, when not the row selection of ``rows`` (:attr:`row_map`)
    _map = None

    def __post_init__(self) -> None:
        r = self.robot
        joints = tuple(r.term_joints)
        named = named_joints(self.joint_terms if isinstance(self.joint_terms, (str, Mapping)) else self.per_joint_terms)
        if isinstance(self.joint_terms, (str, Mapping)):
            self.per_joint_terms = parse_joint_terms(self.joint_terms, joints)
        elif self.per_joint_terms is not None:
            self.per_joint_terms = parse_joint_terms(self.per_joint_terms, joints)
        else:
            bad = [t for t in self.joint_terms if t not in JOINT_TERMS]
            if bad:
                raise RobotModelError(f"unknown joint term(s) {bad}; choose from {JOINT_TERMS}")
        if r.passive_joints:  # a joint without actuator has its friction only (joint_spec.PASSIVE_TERMS)
            per = self.per_joint_terms or {j: tuple(t for t in JOINT_TERMS if t in self.joint_terms) for j in joints}
            self.per_joint_terms = passive_terms(per, r.passive_joints, named)
        if self.per_joint_terms is not None:
            union = {t for ts in self.per_joint_terms.values() for t in ts}
            self.joint_terms = tuple(t for t in JOINT_TERMS if t in union)
            if all(self.per_joint_terms[j] == self.joint_terms for j in joints):
                self.per_joint_terms = None  # uniform after all
        self.joint_terms = tuple(t for t in JOINT_TERMS if t in self.joint_terms)
        if isinstance(self.coulomb_smoothing, Mapping):
            self.coulomb_smoothing = per_joint_values(self.coulomb_smoothing, joints, "coulomb_smoothing")
        elif not (np.isfinite(self.coulomb_smoothing) and self.coulomb_smoothing >= 0):
            raise RobotModelError(f"coulomb_smoothing must be a finite number >= 0, got {self.coulomb_smoothing!r}")
        if self.friction_law not in FRICTION_LAWS:
            raise RobotModelError(f"friction_law must be one of {FRICTION_LAWS}, got {self.friction_law!r}")
        self.stribeck_velocity = per_joint_values(self.stribeck_velocity, joints, "stribeck_velocity") or None
        self.rest_velocity = per_joint_values(self.rest_velocity, joints, "rest_velocity") or None
        need = [j for j in joints if "stribeck" in self.terms_of(j)]
        if need:  # vs of joints not given: DEFAULT_STRIBECK_VELOCITY (identification.friction searches it)
            vs = dict(self.stribeck_velocity or {})
            bad = [j for j in need if vs.get(j, 1.0) <= 0]
            if bad:
                raise RobotModelError(f"Stribeck velocity vs of {bad} must be > 0")
            self.stribeck_velocity = {j: vs.get(j, DEFAULT_STRIBECK_VELOCITY) for j in need}
        self.presliding = parse_presliding(self.presliding, joints, [j for j in joints if "presliding" in self.terms_of(j)])
        if self.rows is None:
            self.rows = "all" if self.robot.floating_base else "actuated"
        self.labels = [f"{b}.{p}" for b in r.body_names for p in PARAMETER_NAMES]
        self.labels += [f"{j}.{t}" for j in r.term_joints for t in self.joint_terms]
        self._act = r.term_v_indices  # velocity columns of the term joints (actuated, then passive)
        self._row_idx = self._act if self.rows == "actuated" else np.arange(r.nv)
        # position of each term joint among the kept rows (the first n_actuated: the measured ones)
        self._act_row = (
            np.arange(len(self._act)) if self.rows == "actuated" else self._act
        )

    # ---- sizes -------------------------------------------------------------------
    @property
    def n_body_params(self) -> int:
        return 10 * self.robot.n_bodies

    @property
    def n_drive_params(self) -> int:
        return sum(d.n_params for d in self.drives)

    @property
    def n_block_params(self) -> int:
        """Columns of the dense block: bodies and drive terms (:meth:`block_regressor`)."""
        return self.n_body_params + self.n_drive_params

    @property
    def n_params(self) -> int:
        return self.n_block_params + len(self.joint_terms) * len(self.robot.term_joints)

    @property
    def n_rows(self) -> int:
        """Equations per sample."""
        return len(self._row_idx)

    @property
    def row_names(self) -> list[str]:
        m = self.robot.model
        if self.rows == "actuated":
            return list(self.robot.term_joints)
        names = [f"base_{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")] if self.robot.floating_base else []
        return names + list(self.robot.joint_names) if self.robot.floating_base else [
            m.names[j] for j in range(1, m.njoints)
        ]

    @property
    def row_map(self) -> RowMap:
        """The map from the nv rows of the equations of motion to the kept rows
        (:class:`~.rowmap.ActuatedRows`: the actuated rows, or all rows; a subclass's own map
        otherwise, e.g. Gᵀ of a transmission)."""
        return self._map if self._map is not None else ActuatedRows(self._row_idx, tuple(self.row_names))

    @property
    def measured_wrench(self) -> bool:
        """True when measured contact wrenches are on the known side (:attr:`row_map`)."""
        return self.row_map.measured_wrench

    def terms_of(self, joint: str) -> tuple[str, ...]:
        """The joint terms ``joint`` really has (a subset of ``joint_terms``)."""
        per = getattr(self, "per_joint_terms", None)
        return tuple(per[joint]) if per is not None else tuple(self.joint_terms)

    @property
    def term_mask(self) -> np.ndarray:
        """(n_term_joints, n_terms) bool: True where a joint has the term of that column."""
        joints = self.robot.term_joints
        return np.array([[t in self.terms_of(j) for t in self.joint_terms] for j in joints],
                        dtype=bool).reshape(len(joints), len(self.joint_terms))

    @property
    def fixed_zero_index(self) -> np.ndarray:
        """Parameter indices of terms a joint does not have (zero columns, fixed at 0)."""
        return np.array([self.joint_term_index(j, t) for j in self.robot.term_joints for t in self.joint_terms
                         if t not in self.terms_of(j)], dtype=int)

    def smoothing_of(self, joint: str) -> float:
        """Coulomb smoothing velocity ε of ``joint`` (0: sgn)."""
        eps = self.coulomb_smoothing
        return float(eps.get(joint, 0.0)) if isinstance(eps, Mapping) else float(eps)

    def joint_term_index(self, joint: str, term: str) -> int:
        """Index of joint term ``term`` of term joint ``joint`` (actuated or passive), or of parameter
        ``term`` (fv, fc, offset, inertia, k, k_rest) of drive ``joint``."""
        if term in self.joint_terms and joint in self.robot.term_joints:
            k = list(self.robot.term_joints).index(joint)
            return self.n_block_params + k * len(self.joint_terms) + self.joint_terms.index(term)
        label = f"{joint}.{term}"
        try:
            return self.labels.index(label, self.n_body_params)
        except ValueError:
            raise RobotModelError(f"no parameter '{label}'; joint and drive parameters are "
                                  f"{self.labels[self.n_body_params:]}") from None

    def drive_slices(self) -> list[slice]:
        """Parameter slice of each drive, in ``drives`` order."""
        out, c = [], self.n_body_params
        for d in self.drives:
            out.append(slice(c, c + d.n_params))
            c += d.n_params
        return out

    def drive_values(self, params: np.ndarray) -> dict[str, dict[str, float]]:
        """Drive parameters of a parameter vector, by drive name (empty without drives)."""
        return {
            d.name: dict(zip(d.param_names, map(float, np.asarray(params)[s])))
            for d, s in zip(self.drives, self.drive_slices())
        }

    def prior(self) -> np.ndarray:
        """The model's own parameters: URDF inertials, zero friction, model armature."""
        p = np.zeros(self.n_params)
        p[: self.n_body_params] = self.robot.inertial_parameters()
        if "armature" in self.joint_terms:
            for j, ia in zip(self.robot.actuated_joints, self.robot.armature):
                p[self.joint_term_index(j, "armature")] = ia
        if getattr(self, "per_joint_terms", None) is not None:
            p[self.fixed_zero_index] = 0.0
        return p

    # ---- evaluation --------------------------------------------------------------
    def state(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinocchio (Q, V, A) arrays for a trajectory, checking joint names and fields."""
        r = self.robot
        if traj.v is None or traj.a is None:
            missing = "v" if traj.v is None else "a"
            raise DataError(
                f"trajectory has no '{missing}'; compute derivatives first "
                "(sensorless.data.savgol_derivatives) or map the column",
                traj.source,
            )
        traj = in_robot_order(r, traj)
        if r.floating_base and self.rows == "all" and (traj.base_q is None or traj.base_v is None or traj.base_a is None):
            raise DataError("a floating-base robot needs base_q, base_v and base_a in the trajectory", traj.source)
        Q = r.full_configuration(traj.q, traj.base_q)
        V = r.full_velocity(traj.v, traj.base_v)
        A = r.full_velocity(traj.a, traj.base_a)
        return Q, V, A

    def pinocchio_state(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinocchio (Q, V, A) of the model for the structure's arrays (from :meth:`state`):
        the identity here; a transmission maps its coordinates to the tree."""
        return Q, V, A

    def target(self, traj: Trajectory) -> np.ndarray:
        """Measured effort on the kept rows, shape (N, n_rows)."""
        r = self.robot
        if traj.tau is None:
            raise DataError(no_effort_message(traj), traj.source)
        tau = in_robot_order(r, traj).tau
        cols = [r.joint_names.index(j) for j in r.actuated_joints]
        y = np.zeros((len(traj), self.n_rows))
        y[:, self._act_row[: len(cols)]] = tau[:, cols]  # passive rows: 0, their generalized force
        return y

    def body_regressor(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Rigid-body block M Y(q, v, v̇), shape (N, n_rows, 10·n_bodies): Pinocchio's regressor
        at :meth:`pinocchio_state`, one call per sample, on the identified bodies' columns, mapped
        by a constant :attr:`row_map` (a per-sample map is applied when folding: here its kept rows)."""
        N = Q.shape[0]
        Wb = np.empty((N, self.n_rows, self.n_body_params)) if out is None else out[:N]
        Q, V, A = self.pinocchio_state(Q, V, A)
        model, data, f = self.robot.model, self.robot.data, pin.computeJointTorqueRegressor
        rm = self.row_map
        if self._body_cols is not None or not (rm.selects_rows or rm.per_sample):
            cols = slice(None) if self._body_cols is None else self._body_cols
            Y = np.empty((N, model.nv, self.n_body_params))
            for i in range(N):
                Y[i] = f(model, data, Q[i], V[i], A[i])[:, cols]
            Wb[...] = rm.apply(Y)
        elif (kernel := native_regressor(model)) is not None:  # one C++ call per chunk (regressor.native)
            direct = Wb.flags.c_contiguous or (kernel.strided and Wb.strides[-1] == Wb.itemsize)
            dst = Wb if direct else np.empty(Wb.shape)
            kernel(Q, V, A, self._row_idx, dst, threads=native_threads())
            if dst is not Wb:
                Wb[...] = dst
        # zip over row views and `w[...] =` keep the Python work per sample to the call itself
        elif self.n_rows == self.robot.nv:
            for w, q, v, a in zip(Wb, Q, V, A):
                w[...] = f(model, data, q, v, a)
        else:
            rows = self._row_idx
            for w, q, v, a in zip(Wb, Q, V, A):
                w[...] = f(model, data, q, v, a)[rows]
        return Wb

    def drive_columns(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Drive-term block (N, n_rows, n_drive_params): the column of parameter p of drive d is
        g_d f_{d,p}(Q, V, A) on the kept rows (the structure's arrays, e.g. coordinates θ)."""
        N = np.atleast_2d(Q).shape[0]
        out = np.zeros((N, self.n_rows, self.n_drive_params))
        nb = self.n_body_params
        for d, s in zip(self.drives, self.drive_slices()):
            F = d.features(Q, V, A, self.coulomb_smoothing)  # (N, n_p)
            out[:, :, s.start - nb : s.stop - nb] = d.g[self._row_idx][None, :, None] * F[:, None, :]
        return out

    def block_regressor(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The dense column block [bodies | drive terms], shape (N, n_rows, n_block_params)."""
        N = Q.shape[0]
        W = np.empty((N, self.n_rows, self.n_block_params)) if out is None else out[:N]
        self.body_regressor(Q, V, A, out=W[:, :, : self.n_body_params])
        if self.drives:
            W[:, :, self.n_body_params :] = self.drive_columns(Q, V, A)
        return W

    def row_body_columns(self) -> list[tuple[int, int]]:
        """Per kept row, the column range (c0, c1) of the body block that can be non-zero.

        Row v (a dof of joint j) of the joint-torque regressor only sees the bodies of the
        subtree of j: τ_j = S_jᵀ Σ_{b ∈ subtree(j)} f_b(π_b). A child's index is larger than
        its parent's, so those bodies lie in columns 10(j−1) … 10·max(subtree(j)): one contiguous
        range (exactly the subtree when joints are numbered depth-first, as Pinocchio's parsers do;
        a superset with zero columns otherwise).
        """
        m = self.robot.model
        owner = np.empty(m.nv, dtype=int)
        for j in range(1, m.njoints):
            owner[m.idx_vs[j] : m.idx_vs[j] + m.nvs[j]] = j
        out = []
        for v in self._row_idx:
            j = int(owner[v])
            out.append((10 * (j - 1), 10 * max(m.subtrees[j])))
        return out

    def joint_features(self, V: np.ndarray, A: np.ndarray, Z: "np.ndarray | None" = None) -> np.ndarray:
        """Joint-term block, shape (N, n_term_joints, n_terms): [v, T, T − (1 − e^{−(v/vs)²}) sgn v, 1, v̇, s_c]
        per term joint (T = tanh(v/ε), sgn v for ε = 0; both 0 for |v| ≤ δ, the rest velocity; s_c the
        presliding state ``Z`` of these rows, :meth:`friction_states`);
        zero where a joint lacks a term."""
        v = V[:, self._act]
        if not self.joint_terms:
            return np.zeros(v.shape + (0,))
        x = self.term_inputs(v, A[:, self._act], Z)
        F = np.stack([joint_term(t).column(x) for t in self.joint_terms], axis=2)
        if getattr(self, "per_joint_terms", None) is not None:
            F *= self.term_mask[None, :, :]
        return F

    def term_inputs(self, v: np.ndarray, a: np.ndarray, Z: "np.ndarray | None" = None) -> TermInputs:
        """The signals the joint-term columns are made of (:class:`~.joint_terms.TermInputs`), for term-joint
        velocities ``v`` and accelerations ``a`` (N, n_term_joints): this structure's ε, δ, vs and law."""
        joints = self.robot.term_joints
        vs = np.array([(self.stribeck_velocity or {}).get(j, 1.0) for j in joints])
        eps = np.array([self.smoothing_of(j) for j in joints])
        return TermInputs(v, a, eps, self._rest_velocities(), vs, self.friction_law, Z)

    def friction_states(self, traj: Trajectory) -> "np.ndarray | None":
        """The presliding state s_c of each term joint along the log ``traj`` from 0 (N, n_term_joints,
        :func:`~.friction_state.presliding_states`; 0 for a joint without the term); None when no joint
        has ``presliding`` (the model is then memoryless)."""
        if "presliding" not in self.joint_terms:
            return None
        joints, laws = self.robot.term_joints, self.presliding or {}
        if (missing := [j for j in joints if "presliding" in self.terms_of(j) and j not in laws]) or traj.v is None:
            raise DataError(f"the presliding state needs the joint velocities and a presliding distance for "
                            f"{missing} (identify chooses it)", traj.source)
        traj, cols = in_robot_order(self.robot, traj), [self.robot.joint_names.index(j) for j in joints]
        return presliding_states(traj.q[:, cols], traj.v[:, cols], [laws.get(j) for j in joints])

    def _rest_velocities(self) -> np.ndarray:
        rest = getattr(self, "rest_velocity", None) or {}
        return np.array([rest.get(j, 0.0) for j in self.robot.term_joints])

    def coulomb_sign(self, v: np.ndarray) -> np.ndarray:
        """:func:`.friction_columns.coulomb_sign` of term-joint velocities ``v`` (N, n_term_joints)."""
        eps = np.array([self.smoothing_of(j) for j in self.robot.term_joints])
        return coulomb_sign(v, eps, self._rest_velocities())

    def sliding_sign(self, v: np.ndarray) -> np.ndarray:
        """:func:`.friction_columns.sliding_sign` of term-joint velocities ``v`` (N, n_term_joints)."""
        return sliding_sign(v, self._rest_velocities())

    def fit_mask(self, V: np.ndarray) -> "np.ndarray | None":
        """(N, n_rows) 0/1 weights of the equations in the fit (:func:`.friction_columns.fit_keep` on
        each term joint's row); None when nothing is left out."""
        law = [any(joint_term(t).reversal for t in self.terms_of(j)) for j in self.robot.term_joints]
        keep_j = fit_keep(V[:, self._act], self._rest_velocities(), np.array(law, dtype=bool))
        if keep_j is None:
            return None
        keep = np.ones((V.shape[0], self.n_rows))
        keep[:, self.term_rows] = keep_j
        return keep

    @property
    def term_rows(self) -> np.ndarray:
        """Index, among the kept rows, of each term joint's equation (actuated, then passive)."""
        return self._act_row

    @property
    def actuated_rows(self) -> np.ndarray:
        """Index, among the kept rows, of each actuated joint's (measured) equation."""
        return self._act_row[: self.robot.n_actuated]

    def evaluate(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, Z: "np.ndarray | None" = None) -> np.ndarray:
        """Full regressor (N, n_rows, n_params) at the structure's arrays (:meth:`state`; ``Z``: :meth:`friction_states`)."""
        Q, V, A = np.atleast_2d(Q), np.atleast_2d(V), np.atleast_2d(A)
        N = Q.shape[0]
        W = np.zeros((N, self.n_rows, self.n_params))
        self.block_regressor(Q, V, A, out=W[:, :, : self.n_block_params])
        F = self.joint_features(V, A, Z)
        nt = len(self.joint_terms)
        for k, row in enumerate(self._act_row):
            c = self.n_block_params + k * nt
            W[:, row, c : c + nt] = F[:, k]
        return W

    def equations_of_motion(self) -> "ModelStructure":
        """The unmapped per-joint structure on the rows of known generalized force (a floating base's 6
        and all joints, or the term joints of a fixed base: actuated, then passive), with this structure's
        joint terms: its parameters are the first ``n_params`` of this one's (a contact structure's
        wrench biases come after). The equations of motion without a row map, e.g. to estimate the
        external (contact) forces a contact projection removes."""
        return ModelStructure(self.robot, joint_terms=self.joint_terms, coulomb_smoothing=self.coulomb_smoothing,
                              rows="all" if self.robot.floating_base else "actuated",
                              per_joint_terms=self.per_joint_terms, stribeck_velocity=self.stribeck_velocity,
                              rest_velocity=self.rest_velocity, presliding=self.presliding)

    def fold(self, ne, traj: Trajectory) -> None:
        """Add one chunk's assembled equations (W, y) to normal equations ``ne``; used by
        :func:`~.compress.compress` for row maps that change per sample (``row_map.per_sample``)."""
        ne.add(self.regressor(traj), self.target(traj))

    def regressor(self, traj: Trajectory) -> np.ndarray:
        """Regressor of a (short) trajectory, shape (N, n_rows, n_params)."""
        return self.evaluate(*self.state(traj), self.friction_states(traj))

    def torques(self, params: np.ndarray, traj: Trajectory, chunk: int = 4096) -> np.ndarray:
        """Predicted effort W π on the kept rows (N, n_rows), in chunks (presliding states from 0 first)."""
        out = np.empty((len(traj), self.n_rows))
        Z = self.friction_states(traj)
        for s in range(0, len(traj), chunk):
            part = traj.take(slice(s, s + chunk))
            out[s : s + len(part)] = self.evaluate(*self.state(part), None if Z is None else Z[s : s + len(part)]) @ params
        return out

    def settings(self) -> dict:
        """Round-trips through ``result.json`` (:func:`sensorless.torque_models.load_parameters`).
        ``coulomb_smoothing`` stays one number (the median ε) for older readers; the per-joint
        values are in ``coulomb_smoothing_by_joint``."""
        eps = self.coulomb_smoothing
        out = {
            "joint_terms": list(self.joint_terms),
            "coulomb_smoothing": float(np.median(list(eps.values()))) if isinstance(eps, Mapping) and eps else
            (0.0 if isinstance(eps, Mapping) else eps),
            "rows": self.rows,
        }
        if isinstance(eps, Mapping):
            out["coulomb_smoothing_by_joint"] = dict(eps)
        if getattr(self, "per_joint_terms", None) is not None:
            out["joint_terms_by_joint"] = {j: list(t) for j, t in self.per_joint_terms.items()}
        if getattr(self, "stribeck_velocity", None):
            out["stribeck_velocity"] = dict(self.stribeck_velocity)
        if "stribeck" in self.joint_terms:
            out["friction_law"] = getattr(self, "friction_law", "blend")
        if getattr(self, "rest_velocity", None):
            out["rest_velocity"] = dict(self.rest_velocity)
        return {**out, "presliding": {j: dict(p) for j, p in self.presliding.items()}} if self.presliding else out


def in_robot_order(robot: Robot, traj: Trajectory) -> Trajectory:
    """The trajectory with joint columns in ``robot.joint_names`` order (JointNameError if impossible)."""
    if traj.joint_names == robot.joint_names:
        return traj
    robot.joint_order(traj.joint_names, traj.source)
    return traj.select_joints(list(robot.joint_names))

"""Regressor terms: the linear map from parameters to joint torques.

Inverse dynamics with per-joint friction and rotor inertia is linear in the parameters:

    τ_j = [Y(q, v, v̇) π]_j + fv_j v_j + fc_j sgn(v_j) + o_j + Ia_j v̇_j

* ``Y`` is Pinocchio's joint-torque regressor (``computeJointTorqueRegressor``), with
  π the stacked body parameters (10 per body, see :mod:`sensorless.parameters`).
* Joint terms, per actuated joint and in this order when enabled: viscous ``fv``,
  Coulomb ``fc`` (``sgn`` is ``tanh(v / coulomb_smoothing)`` when a smoothing velocity
  is given), constant ``offset`` and ``armature`` (reflected rotor inertia).

The full parameter vector is ``[π (10 · n_bodies), terms of joint 1, terms of joint 2, …]``.
Which rows of the equation are used (the "row map") is chosen by ``rows``:
``"actuated"`` keeps the actuated joints' rows (fixed-base arms), ``"all"`` keeps all
nv rows with τ_full = Sᵀ τ (a floating base in flight; contact maps come with the
contact module).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError
from ..parameters import PARAMETER_NAMES
from ..robot import Robot

__all__ = ["JOINT_TERMS", "ModelStructure"]

JOINT_TERMS = ("fv", "fc", "offset", "armature")


@dataclass
class ModelStructure:
    """Which columns and rows make up the identification model of a robot."""

    robot: Robot
    joint_terms: tuple[str, ...] = ("fv", "fc", "offset", "armature")
    coulomb_smoothing: float = 0.0
    rows: Literal["actuated", "all"] | None = None
    labels: list[str] = field(init=False)

    def __post_init__(self) -> None:
        bad = [t for t in self.joint_terms if t not in JOINT_TERMS]
        if bad:
            raise RobotModelError(f"unknown joint term(s) {bad}; choose from {JOINT_TERMS}")
        self.joint_terms = tuple(t for t in JOINT_TERMS if t in self.joint_terms)
        if self.rows is None:
            self.rows = "all" if self.robot.floating_base else "actuated"
        r = self.robot
        self.labels = [f"{b}.{p}" for b in r.body_names for p in PARAMETER_NAMES]
        self.labels += [f"{j}.{t}" for j in r.actuated_joints for t in self.joint_terms]
        self._act = r.actuated_v_indices
        self._row_idx = self._act if self.rows == "actuated" else np.arange(r.nv)
        # position of each actuated joint among the kept rows
        self._act_row = (
            np.arange(r.n_actuated) if self.rows == "actuated" else self._act
        )

    # ---- sizes -------------------------------------------------------------------
    @property
    def n_body_params(self) -> int:
        return 10 * self.robot.n_bodies

    @property
    def n_params(self) -> int:
        return self.n_body_params + len(self.joint_terms) * self.robot.n_actuated

    @property
    def n_rows(self) -> int:
        """Equations per sample."""
        return len(self._row_idx)

    @property
    def row_names(self) -> list[str]:
        m = self.robot.model
        if self.rows == "actuated":
            return list(self.robot.actuated_joints)
        names = [f"base_{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")] if self.robot.floating_base else []
        return names + list(self.robot.joint_names) if self.robot.floating_base else [
            m.names[j] for j in range(1, m.njoints)
        ]

    def joint_term_index(self, joint: str, term: str) -> int:
        k = list(self.robot.actuated_joints).index(joint)
        return self.n_body_params + k * len(self.joint_terms) + self.joint_terms.index(term)

    def prior(self) -> np.ndarray:
        """The model's own parameters: URDF inertials, zero friction, model armature."""
        p = np.zeros(self.n_params)
        p[: self.n_body_params] = self.robot.inertial_parameters()
        if "armature" in self.joint_terms:
            for j, ia in zip(self.robot.actuated_joints, self.robot.armature):
                p[self.joint_term_index(j, "armature")] = ia
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
        traj = _in_robot_order(r, traj)
        if r.floating_base and self.rows == "all" and (traj.base_q is None or traj.base_v is None or traj.base_a is None):
            raise DataError("a floating-base robot needs base_q, base_v and base_a in the trajectory", traj.source)
        Q = r.full_configuration(traj.q, traj.base_q)
        V = r.full_velocity(traj.v, traj.base_v)
        A = r.full_velocity(traj.a, traj.base_a)
        return Q, V, A

    def target(self, traj: Trajectory) -> np.ndarray:
        """Measured effort on the kept rows, shape (N, n_rows)."""
        r = self.robot
        if traj.tau is None:
            raise DataError("trajectory has no torque/effort ('tau')", traj.source)
        tau = _in_robot_order(r, traj).tau
        cols = [r.joint_names.index(j) for j in r.actuated_joints]
        y = np.zeros((len(traj), self.n_rows))
        y[:, self._act_row] = tau[:, cols]
        return y

    def body_regressor(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Rigid-body block, shape (N, n_rows, 10·n_bodies). One Pinocchio call per sample."""
        N = Q.shape[0]
        Wb = np.empty((N, self.n_rows, self.n_body_params)) if out is None else out[:N]
        model, data, f = self.robot.model, self.robot.data, pin.computeJointTorqueRegressor
        # zip over row views and `w[...] =` keep the Python work per sample to the call itself
        if self.n_rows == self.robot.nv:
            for w, q, v, a in zip(Wb, Q, V, A):
                w[...] = f(model, data, q, v, a)
        else:
            rows = self._row_idx
            for w, q, v, a in zip(Wb, Q, V, A):
                w[...] = f(model, data, q, v, a)[rows]
        return Wb

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

    def joint_features(self, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Joint-term block, shape (N, n_actuated, n_terms): [v, sgn v, 1, v̇] per actuated joint."""
        v = V[:, self._act]
        cols = {
            "fv": lambda: v,
            "fc": lambda: np.sign(v) if self.coulomb_smoothing <= 0 else np.tanh(v / self.coulomb_smoothing),
            "offset": lambda: np.ones_like(v),
            "armature": lambda: A[:, self._act],
        }
        if not self.joint_terms:
            return np.zeros(v.shape + (0,))
        return np.stack([cols[t]() for t in self.joint_terms], axis=2)

    @property
    def actuated_rows(self) -> np.ndarray:
        """Index, among the kept rows, of each actuated joint's equation."""
        return self._act_row

    def evaluate(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Full regressor of N samples, shape (N, n_rows, n_params)."""
        N = Q.shape[0]
        W = np.zeros((N, self.n_rows, self.n_params))
        self.body_regressor(Q, V, A, out=W[:, :, : self.n_body_params])
        F = self.joint_features(V, A)
        nt = len(self.joint_terms)
        for k, row in enumerate(self._act_row):
            c = self.n_body_params + k * nt
            W[:, row, c : c + nt] = F[:, k]
        return W

    def regressor(self, traj: Trajectory) -> np.ndarray:
        """Regressor of a (short) trajectory, shape (N, n_rows, n_params)."""
        return self.evaluate(*self.state(traj))

    def torques(self, params: np.ndarray, traj: Trajectory, chunk: int = 4096) -> np.ndarray:
        """Predicted effort W π on the kept rows, shape (N, n_rows), evaluated in chunks."""
        out = np.empty((len(traj), self.n_rows))
        for s in range(0, len(traj), chunk):
            part = traj.take(slice(s, s + chunk))
            out[s : s + len(part)] = self.evaluate(*self.state(part)) @ params
        return out

    def settings(self) -> dict:
        return {
            "joint_terms": list(self.joint_terms),
            "coulomb_smoothing": self.coulomb_smoothing,
            "rows": self.rows,
        }


def _in_robot_order(robot: Robot, traj: Trajectory) -> Trajectory:
    """The trajectory with joint columns in ``robot.joint_names`` order (JointNameError if impossible)."""
    if traj.joint_names == robot.joint_names:
        return traj
    robot.joint_order(traj.joint_names, traj.source)
    return traj.select_joints(list(robot.joint_names))

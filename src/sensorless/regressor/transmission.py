"""Transmissions: a kinematic tree whose joints are linear in independent coordinates.

Closed chains and coupled drives are modelled as a Pinocchio *tree* whose joint values
are linear in fewer independent (or motor) coordinates θ,

    q = G θ + q₀,   v = G θ̇,   v̇ = G θ̈        (G: n_joints × n_coordinates, constant).

* A parallelogram is a serial tree with extra revolute joints whose angles are ±θ_k
  (rows of G with one non-zero entry); a counterweight is one more body on such a joint.
* A cable-coupled wrist is G = the motor-to-joint matrix, so θ are motor angles.

By virtual work the generalised forces of the coordinates are τ_θ = Gᵀ τ_q, so with
Pinocchio's joint-torque regressor Y(q, v, v̇) (τ_q = Y π)

    τ_θ = Gᵀ Y(Gθ + q₀, Gθ̇, Gθ̈) π + Σ_d g_d f_d,

where f_d are the drive terms of :mod:`.drive_terms` (friction, motor inertia and springs
on drive coordinates s_d = g_dᵀθ). :class:`TransmissionStructure` is a
:class:`~sensorless.regressor.ModelStructure` in coordinate space made of three parts:

* its ``robot``, a :class:`CoordinateRobot` (a Robot-like view whose joints are the
  coordinates), so ``state(traj)`` returns (θ, θ̇, θ̈) and ``target`` the coordinates' forces;
* the coordinate → tree state map ``pinocchio_state`` (q = Gθ + q₀, v = Gθ̇, v̇ = Gθ̈);
* the row map Gᵀ (:class:`~.rowmap.TransmissionRows`) and the drive terms (``drives``).

``evaluate``, ``compress``, ``base_parameters`` and ``identify`` are ModelStructure's. The
drive terms couple several equation rows through one parameter, so they are dense block
columns next to the bodies (``block_regressor``) and there are no per-joint terms.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..errors import JointNameError, RobotModelError
from ..parameters import PARAMETER_NAMES
from ..robot import Actuation, Robot, kinematics_summary
from .drive_terms import DriveTerm
from .rowmap import TransmissionRows
from .terms import ModelStructure

__all__ = ["CoordinateRobot", "TransmissionStructure", "add_body_joint", "coupling_matrix"]


def coupling_matrix(
    joint_names: Sequence[str],
    coordinates: Sequence[str],
    rules: Mapping[str, Mapping[str, float]],
) -> np.ndarray:
    """G (n_joints × n_coordinates) from ``{joint: {coordinate: coefficient}}``.

    Every joint must appear in ``rules`` (a joint equal to a coordinate: ``{"q1": {"q1": 1}}``).
    """
    joint_names, coordinates = list(joint_names), list(coordinates)
    missing = [j for j in joint_names if j not in rules]
    unknown = [j for j in rules if j not in joint_names]
    if missing or unknown:
        raise RobotModelError(f"coupling rules: missing joint(s) {missing}, unknown joint(s) {unknown}")
    G = np.zeros((len(joint_names), len(coordinates)))
    for j, row in rules.items():
        for c, coef in row.items():
            if c not in coordinates:
                raise RobotModelError(f"coupling rule of joint '{j}' names unknown coordinate '{c}'; coordinates are {coordinates}")
            G[joint_names.index(j), coordinates.index(c)] = float(coef)
    return G


def add_body_joint(
    model: pin.Model,
    parent: int,
    name: str,
    placement: pin.SE3,
    kind: str = "revolute",
    inertia: pin.Inertia | None = None,
) -> int:
    """Add a 1-DoF joint about (revolute) or along (prismatic) its local z axis, carrying
    ``inertia`` (expressed in the joint frame); returns the joint id. A frame of the same
    name is added so Cartesian constraints and Jacobians can refer to it."""
    if kind not in ("revolute", "prismatic"):
        raise RobotModelError(f"joint '{name}': kind must be 'revolute' or 'prismatic', got {kind!r}")
    jm = pin.JointModelRZ() if kind == "revolute" else pin.JointModelPZ()
    jid = model.addJoint(parent, jm, placement, name)
    model.appendBodyToJoint(jid, inertia if inertia is not None else pin.Inertia.Zero(), pin.SE3.Identity())
    model.addJointFrame(jid)
    return jid


class CoordinateRobot(Actuation):
    """Robot-like view of a tree driven by independent coordinates.

    Joint-level attributes (``joint_names``, ``nv``, limits, ``full_configuration``) refer
    to the coordinates; body-level attributes (``body_names``, ``n_bodies``,
    ``inertial_parameters``) to the identified bodies of the tree; ``model``/``data`` are
    the tree's Pinocchio model (nv = number of tree joints).
    """

    floating_base = False
    coupled = True

    def __init__(
        self,
        tree: Robot,
        coordinates: Sequence[str],
        bodies: Sequence[str],
        actuated: Sequence[str],
        lower: np.ndarray,
        upper: np.ndarray,
        velocity: np.ndarray,
        name: str | None = None,
    ) -> None:
        self.tree = tree
        self.joint_names = tuple(coordinates)
        self.actuated_joints = tuple(actuated)
        self.body_names = tuple(bodies)
        self._lower, self._upper, self._vel = np.asarray(lower, float), np.asarray(upper, float), np.asarray(velocity, float)
        self.name = name or tree.name
        self.source = tree.source
        self.urdf_path = None
        self._body_ids = np.array([tree.body_names.index(b) for b in self.body_names], dtype=int)

    # sizes ---------------------------------------------------------------------
    model = property(lambda self: self.tree.model)
    data = property(lambda self: self.tree.data)
    nq = property(lambda self: len(self.joint_names))
    nv = property(lambda self: len(self.joint_names))
    n_bodies = property(lambda self: len(self.body_names))
    n_actuated = property(lambda self: len(self.actuated_joints))

    @property
    def body_indices(self) -> np.ndarray:
        """Index of each identified body among the tree's bodies."""
        return self._body_ids.copy()

    def v_index(self, joint: str) -> int:
        try:
            return self.joint_names.index(joint)
        except ValueError:
            raise RobotModelError(f"{self.name}: unknown coordinate '{joint}'; coordinates are {list(self.joint_names)}") from None

    q_index = v_index

    @property
    def transmission_matrix(self) -> "np.ndarray | None":
        """G (n_tree_joints × n_coordinates), or None before a structure sets it."""
        return getattr(self, "G", None)

    @property
    def armature(self) -> np.ndarray:
        return np.zeros(self.n_actuated)

    def is_continuous(self, joint: str) -> bool:
        return False

    def is_revolute(self, joint: str) -> bool:
        """False when every tree joint the coordinate drives is prismatic."""
        G = getattr(self, "G", None)
        if G is None:
            return True
        k = self.v_index(joint)
        driven = [self.tree.joint_names[j] for j in np.flatnonzero(G[:, k])]
        return not driven or any(self.tree.is_revolute(j) for j in driven)

    def joint_order(self, names: Sequence[str], source: str = "<trajectory>") -> np.ndarray:
        names = list(names)
        unknown = [n for n in names if n not in self.joint_names]
        missing = [n for n in self.joint_names if n not in names]
        if unknown or missing:
            raise JointNameError(
                f"unknown coordinate(s) {unknown}; missing coordinate(s) {missing} "
                f"('{self.name}' is driven by {list(self.joint_names)})",
                source,
            )
        return np.array([names.index(n) for n in self.joint_names], dtype=int)

    def full_configuration(self, q_joints: np.ndarray, base_q: np.ndarray | None = None) -> np.ndarray:
        return np.array(np.atleast_2d(q_joints), dtype=float)

    def full_velocity(self, v_joints: np.ndarray, base_v: np.ndarray | None = None) -> np.ndarray:
        return np.array(np.atleast_2d(v_joints), dtype=float)

    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        return self._lower.copy(), self._upper.copy()

    def velocity_limits(self) -> np.ndarray:
        return self._vel.copy()

    def inertial_parameters(self) -> np.ndarray:
        """Stacked parameters (10 per identified body) of the tree's model."""
        m = self.tree.model
        return np.concatenate([m.inertias[int(k) + 1].toDynamicParameters() for k in self._body_ids]) if len(self._body_ids) else np.zeros(0)

    # ---- frames: Jacobians mapped through G ----------------------------------------
    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of ``name`` in the tree (RobotModelError if unknown)."""
        return self.tree.frame_id(name)

    def tree_state(self, theta, dtheta=None, ddtheta=None) -> tuple[np.ndarray, ...]:
        """Tree arrays Q = Gθ + q₀ (N, nq_tree) and, when given, V = Gθ̇, A = Gθ̈ (N, nv_tree)."""
        G = getattr(self, "G", None)
        if G is None:
            raise RobotModelError(f"{self.name}: coordinate robot without a transmission matrix G")
        off = getattr(self, "offset", np.zeros(G.shape[0]))
        out = [self.tree.full_configuration(np.atleast_2d(theta) @ G.T + off)]
        out += [self.tree.full_velocity(np.atleast_2d(x) @ G.T) for x in (dtheta, ddtheta) if x is not None]
        return tuple(out)

    def make_structure(self, joint_terms=None, coulomb_smoothing: float = 0.0) -> "TransmissionStructure":
        """A structure of this robot with another Coulomb smoothing (``joint_terms``: the
        factory's drive-set name, e.g. the PSM's "authors" / "motors"; None: the factory's default)."""
        factory = getattr(self, "factory", None)
        if factory is None:
            raise RobotModelError(f"{self.name}: no structure factory; build a TransmissionStructure directly")
        return factory(joint_terms, coulomb_smoothing)

    def summary(self) -> dict:
        m = self.tree.model
        return {
            "name": self.name,
            "source": self.source,
            "floating_base": False,
            "coordinates": list(self.joint_names),
            "tree_joints": list(self.tree.joint_names),
            "bodies": list(self.body_names),
            "actuated_joints": list(self.actuated_joints),
            "total_mass": float(sum(m.inertias[int(k) + 1].mass for k in self._body_ids)),
            "kinematics": kinematics_summary(m),
        }


class TransmissionStructure(ModelStructure):
    """Identification structure of a tree with joints q = Gθ + q₀ (see module docstring).

    Parameters: ``[10 per identified body | drive terms in order]``. Rows: the equations
    of ``rows`` (coordinate names; default all coordinates). Bodies not listed in
    ``bodies`` are taken as massless (their columns are dropped).
    """

    def __init__(
        self,
        tree: Robot,
        G: np.ndarray,
        coordinates: Sequence[str],
        *,
        offset: np.ndarray | None = None,
        drives: Sequence[DriveTerm] = (),
        bodies: Sequence[str] | None = None,
        rows: Sequence[str] | None = None,
        limits: tuple[np.ndarray, np.ndarray] | None = None,
        velocity_limits: np.ndarray | None = None,
        coulomb_smoothing: float = 0.0,
        name: str | None = None,
    ) -> None:
        if tree.floating_base:
            raise RobotModelError(f"{tree.name}: transmissions are supported on fixed-base trees only")
        coordinates = tuple(coordinates)
        G = np.array(G, dtype=float)
        nj, nc = len(tree.joint_names), len(coordinates)
        if G.shape != (nj, nc):
            raise RobotModelError(f"G must be (n_tree_joints={nj}, n_coordinates={nc}), got {G.shape}")
        if len(set(coordinates)) != nc:
            raise RobotModelError(f"duplicate coordinate names in {list(coordinates)}")
        if any(tree.is_continuous(j) for j in tree.joint_names):
            raise RobotModelError("continuous (unbounded) tree joints are not supported in a transmission; use revolute joints")
        self.tree = tree
        self.G = G
        self.offset = np.zeros(nj) if offset is None else np.asarray(offset, dtype=float).reshape(nj)
        self.coordinates = coordinates
        self.drives = tuple(drives)
        for d in self.drives:
            if d.g.shape != (nc,):
                raise RobotModelError(f"drive '{d.name}': g has {d.g.size} entries, expected one per coordinate ({nc})")
        names = [d.name for d in self.drives]
        if len(set(names)) != len(names):
            raise RobotModelError(f"duplicate drive names in {names}")
        bodies = tuple(tree.body_names) if bodies is None else tuple(bodies)
        unknown = [b for b in bodies if b not in tree.body_names]
        if unknown:
            raise RobotModelError(f"unknown bodies {unknown}; the tree has {list(tree.body_names)}")
        rows = coordinates if rows is None else tuple(rows)
        bad = [r for r in rows if r not in coordinates]
        if bad:
            raise RobotModelError(f"unknown row coordinate(s) {bad}; coordinates are {list(coordinates)}")
        if limits is None:
            lo, hi = self._induced_limits(tree, G, self.offset)
        else:
            lo, hi = (np.asarray(x, dtype=float).reshape(nc) for x in limits)
        vel = np.full(nc, np.inf) if velocity_limits is None else np.asarray(velocity_limits, dtype=float).reshape(nc)
        # ModelStructure's dataclass fields
        self.robot = CoordinateRobot(tree, coordinates, bodies, rows, lo, hi, vel, name=name)
        self.robot.G = G
        self.robot.offset = self.offset
        self.joint_terms = ()
        self.coulomb_smoothing = float(coulomb_smoothing)
        self.rows = "actuated"
        self.labels = [f"{b}.{p}" for b in bodies for p in PARAMETER_NAMES]
        for d in self.drives:
            self.labels += d.labels
        self._row_idx = np.array([coordinates.index(r) for r in rows], dtype=int)
        self._act = self._row_idx  # the kept coordinates are the actuated ones, row k is coordinate k's
        self._act_row = np.arange(len(rows))
        cols = self.robot.body_indices
        self._body_cols = (10 * cols[:, None] + np.arange(10)[None, :]).ravel()
        self._map = TransmissionRows.from_coupling(G, self._row_idx, coordinates)  # Gᵀ on the kept rows

    @staticmethod
    def _induced_limits(tree: Robot, G: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coordinate box from joints driven by a single coordinate (±π when none)."""
        lo_q, hi_q = tree.position_limits()
        nc = G.shape[1]
        lo, hi = np.full(nc, -np.inf), np.full(nc, np.inf)
        for j in range(G.shape[0]):
            nz = np.flatnonzero(G[j])
            if nz.size != 1 or not (np.isfinite(lo_q[j]) and np.isfinite(hi_q[j])):
                continue
            k, g = nz[0], G[j, nz[0]]
            a, b = sorted(((lo_q[j] - offset[j]) / g, (hi_q[j] - offset[j]) / g))
            lo[k], hi[k] = max(lo[k], a), min(hi[k], b)
        lo = np.where(np.isfinite(lo), lo, -np.pi)
        hi = np.where(np.isfinite(hi), hi, np.pi)
        return lo, hi

    # ---- coordinates → tree (everything else is ModelStructure's on the coordinate robot) ----
    def joint_values(self, theta: np.ndarray) -> np.ndarray:
        """Tree joint positions q = Gθ + q₀, shape (N, n_tree_joints)."""
        return np.atleast_2d(theta) @ self.G.T + self.offset

    def pinocchio_state(self, theta, dtheta, ddtheta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinocchio (Q, V, A) of the tree for coordinate arrays (N, n_coordinates)."""
        t = self.tree
        return (
            t.full_configuration(self.joint_values(theta)),
            t.full_velocity(np.atleast_2d(dtheta) @ self.G.T),
            t.full_velocity(np.atleast_2d(ddtheta) @ self.G.T),
        )

    @classmethod
    def from_settings(cls, tree: Robot, settings: Mapping, **kwargs) -> "TransmissionStructure":
        """Rebuild a structure from its :meth:`settings` (e.g. a ``result.json``) on ``tree``;
        ``kwargs`` (limits, velocity_limits, name) are passed on."""
        joints = list(settings.get("tree_joints", ()))
        if joints != list(tree.joint_names):
            raise RobotModelError(f"saved tree joints {joints} differ from the model's {list(tree.joint_names)}")
        try:
            drives = [DriveTerm(**{k: (tuple(v) if k == "terms" else v) for k, v in d.items()}) for d in settings["drives"]]
            return cls(tree, np.asarray(settings["G"], float), settings["coordinates"], offset=np.asarray(settings["offset"], float),
                       drives=drives, bodies=settings["bodies"], rows=settings.get("rows"),
                       coulomb_smoothing=settings.get("coulomb_smoothing", 0.0), **kwargs)
        except (KeyError, TypeError) as exc:
            raise RobotModelError(f"incomplete transmission settings: {exc}") from None

    def settings(self) -> dict:
        return {
            "structure": "transmission",
            "coordinates": list(self.coordinates),
            "rows": self.row_names,
            "tree_joints": list(self.tree.joint_names),
            "G": self.G.tolist(),
            "offset": self.offset.tolist(),
            "bodies": list(self.robot.body_names),
            "drives": [d.to_dict() for d in self.drives],
            "coulomb_smoothing": self.coulomb_smoothing,
        }

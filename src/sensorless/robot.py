"""Robot: a Pinocchio model with the names and options identification needs.

A :class:`Robot` owns one Pinocchio ``Model`` (and a ``Data`` workspace), the ordered
list of 1-DoF joints, which of them are actuated, and whether the base floats.
:func:`load_robot` accepts a URDF, xacro or MJCF path, or a name of the robot registry
:mod:`sensorless.robots.registry` (example-robot-data's catalogue, robots built in code such as
``dvrk_psm``).

Conventions
-----------
* Every moving joint other than the root is a 1-DoF joint (revolute, prismatic or
  continuous). A floating base is Pinocchio's free-flyer (nq = 7, nv = 6): base pose
  ``[x, y, z, qx, qy, qz, qw]``, base twist expressed in the base frame.
* "Bodies" are Pinocchio's per-joint inertias ``model.inertias[1:]`` (fixed links
  are already merged into their parent by the parser). They are named by their joint.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import pinocchio as pin

from .errors import JointNameError, RobotModelError, did_you_mean, setting
from .parameters import pin_inertia
from .robots.registry import find_robot, robot_names
from .xacro_expand import expand_xacro

__all__ = ["KINEMATICS_TOL", "Actuation", "Robot", "add_frame", "frame_table", "kinematics_difference",
           "kinematics_fingerprint", "kinematics_summary", "kinematics_table", "load_robot"]

#: placements within this many metres (rotation-matrix entries within this much) are the same kinematics:
#: the precision files print, not a different robot
KINEMATICS_TOL = 1e-5


class Actuation:
    """What every robot view shares: the actuated joints' velocity indices, the selection
    matrix S and the transmission. Subclasses give ``actuated_joints``, ``nv`` and ``v_index``.

    ``passive_joints`` have no actuator: their generalized force is known to be zero (apart
    from their own friction), like the unactuated floating base. The *term joints* carry
    per-joint terms (friction, ...): the actuated joints, then the passive ones.

    ``transmission_matrix`` is G of joints q = Gθ + q₀ driven by coordinates θ
    (:class:`~sensorless.regressor.transmission.CoordinateRobot`), None for a plain tree.
    ``coupled``: True for such a coordinate view (its structures come from ``make_structure``).
    ``excitation_box``: the box {"lower", "upper", "velocity", "acceleration"} (arrays per joint) an
    excitation design uses as is, declared by a robot model (the dVRK PSM: the envelope of its logs);
    None: derived from the joint limits (:meth:`~sensorless.excitation.ExcitationLimits.from_robot`)."""

    transmission_matrix: "np.ndarray | None" = None
    coupled: bool = False
    excitation_box: "dict | None" = None
    passive_joints: tuple[str, ...] = ()

    @property
    def actuated_v_indices(self) -> np.ndarray:
        """Velocity indices of the actuated joints, in ``actuated_joints`` order."""
        return np.array([self.v_index(j) for j in self.actuated_joints], dtype=int)

    @property
    def term_joints(self) -> tuple[str, ...]:
        """Joints with per-joint terms: ``actuated_joints`` then ``passive_joints``."""
        return tuple(self.actuated_joints) + tuple(self.passive_joints)

    @property
    def term_v_indices(self) -> np.ndarray:
        """Velocity indices of :attr:`term_joints`."""
        return np.array([self.v_index(j) for j in self.term_joints], dtype=int)

    @property
    def selection(self) -> np.ndarray:
        """Actuation selection matrix S (n_actuated x nv): tau_full = S^T tau."""
        S = np.zeros((self.n_actuated, self.nv))
        S[np.arange(self.n_actuated), self.actuated_v_indices] = 1.0
        return S


@dataclass
class Robot(Actuation):
    """Pinocchio model + joint bookkeeping. Build it with :func:`load_robot`."""

    model: pin.Model
    name: str = "robot"
    source: str = ""
    actuated_joints: tuple[str, ...] = ()
    passive_joints: tuple[str, ...] = ()
    data: pin.Data = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.data = self.model.createData()
        m = self.model
        self.floating_base = m.njoints > 1 and m.joints[1].shortname() == "JointModelFreeFlyer"
        first = 2 if self.floating_base else 1
        names = []
        for j in range(first, m.njoints):
            if m.joints[j].nv != 1:
                raise RobotModelError(
                    f"{self.source or self.name}: joint '{m.names[j]}' has {m.joints[j].nv} DoF; "
                    "only 1-DoF joints (revolute, prismatic, continuous) are supported below the root"
                )
            names.append(m.names[j])
        self.joint_names: tuple[str, ...] = tuple(names)
        self.passive_joints = tuple(self.passive_joints)
        unknown = [j for j in self.passive_joints if j not in self.joint_names]
        if unknown:
            raise JointNameError(
                f"unknown passive joint(s) {unknown}{_hint(unknown, self.joint_names)}; the model has "
                f"{list(self.joint_names)}", self.source or self.name)
        if not self.actuated_joints:
            self.actuated_joints = tuple(j for j in self.joint_names if j not in self.passive_joints)
        unknown = [j for j in self.actuated_joints if j not in self.joint_names]
        if unknown:
            raise JointNameError(
                f"unknown actuated joint(s) {unknown}; the model has {list(self.joint_names)}",
                self.source or self.name,
            )
        both = [j for j in self.passive_joints if j in self.actuated_joints]
        if both:
            raise JointNameError(f"joint(s) {both} are declared both actuated and passive", self.source or self.name)
        self.actuated_joints = tuple(self.actuated_joints)
        self._jid = {m.names[j]: j for j in range(1, m.njoints)}

    # ---- sizes and indices -------------------------------------------------
    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    @property
    def n_bodies(self) -> int:
        """Number of Pinocchio bodies with inertial parameters (joints 1..njoints-1)."""
        return self.model.njoints - 1

    @property
    def body_names(self) -> tuple[str, ...]:
        """One name per body: the name of the joint that carries it."""
        return tuple(self.model.names[1:])

    @property
    def n_actuated(self) -> int:
        return len(self.actuated_joints)

    def joint_id(self, name: str) -> int:
        """Pinocchio joint index of ``name`` (RobotModelError if unknown)."""
        try:
            return self._jid[name]
        except KeyError:
            raise RobotModelError(
                f"{self.source or self.name}: unknown joint '{name}'{_hint([name], self.joint_names)}; known joints: "
                f"{list(self.joint_names)}"
            ) from None

    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of ``name`` (RobotModelError if unknown)."""
        if not self.model.existFrame(name):
            frames = [f.name for f in self.model.frames]
            raise RobotModelError(f"{self.source or self.name}: unknown frame '{name}'{_hint([name], frames)}; "
                                  f"known frames: {frames}")
        return self.model.getFrameId(name)

    def v_index(self, joint: str) -> int:
        return self.model.joints[self.joint_id(joint)].idx_v

    def q_index(self, joint: str) -> int:
        return self.model.joints[self.joint_id(joint)].idx_q

    @property
    def armature(self) -> np.ndarray:
        """Rotor inertia reflected to each actuated joint (from the model)."""
        return np.asarray(self.model.armature)[self.actuated_v_indices].copy()

    def is_continuous(self, joint: str) -> bool:
        return self.model.joints[self.joint_id(joint)].nq == 2

    # ---- parameters -----------------------------------------------------------
    def inertial_parameters(self) -> np.ndarray:
        """Stacked body parameters pi (10 per body, Pinocchio order) of the model."""
        return np.concatenate([self.model.inertias[j].toDynamicParameters() for j in range(1, self.model.njoints)])

    def with_inertial_parameters(self, pi: np.ndarray, name: str | None = None) -> "Robot":
        """A copy of this robot whose body inertias are set from ``pi``."""
        pi = np.asarray(pi, dtype=float)
        if pi.shape != (10 * self.n_bodies,):
            raise RobotModelError(f"expected {10 * self.n_bodies} inertial parameters, got {pi.shape}")
        model = self.model.copy()
        for k in range(self.n_bodies):
            model.inertias[k + 1] = pin_inertia(pi[10 * k : 10 * k + 10])
        out = Robot(model, name=name or self.name, source=self.source, actuated_joints=self.actuated_joints,
                    passive_joints=self.passive_joints)
        for key in ("urdf_path", "package_paths", "description_dir", "locked_joints", "added_frames"):
            if hasattr(self, key):
                setattr(out, key, getattr(self, key))
        return out

    # ---- state assembly -----------------------------------------------------
    def joint_order(self, names: Sequence[str], source: str = "<trajectory>") -> np.ndarray:
        """Column permutation taking a log's joint order to ``self.joint_names``.

        Raises JointNameError naming the unknown or missing joints.
        """
        names = list(names)
        unknown = [n for n in names if n not in self.joint_names]
        missing = [n for n in self.joint_names if n not in names]
        dup = sorted({n for n in names if names.count(n) > 1})
        if unknown or missing or dup:
            parts = []
            if unknown:
                parts.append(f"unknown joint(s) {unknown}")
            if missing:
                parts.append(f"missing joint(s) {missing}")
            if dup:
                parts.append(f"duplicate joint(s) {dup}")
            hints = []
            close = {n: m for n in unknown if (m := did_you_mean(n, missing, n=1, cutoff=0.5))}
            if close:
                hints.append("; ".join(f"for {n!r}, {m}" for n, m in close.items())
                             + " (rename them in the log, or name the log's columns of each joint in the robot's "
                             f"joint order: {setting('joint_names', placeholder='...')})")
            if missing and not unknown:
                hints.append("joints that do not move in the log (a gripper, a locked axis) can be locked: "
                             + setting("lock_joints", list(missing)))
            raise JointNameError(
                "; ".join(parts) + f" (robot '{self.name}' has {list(self.joint_names)})"
                + "".join(f"; {h}" for h in hints), source
            )
        return np.array([names.index(n) for n in self.joint_names], dtype=int)

    def full_configuration(self, q_joints: np.ndarray, base_q: np.ndarray | None = None) -> np.ndarray:
        """Pinocchio configurations (N, nq) from joint positions in ``joint_names`` order."""
        q_joints = np.atleast_2d(q_joints)
        N = q_joints.shape[0]
        Q = np.zeros((N, self.nq))
        if self.floating_base:
            if base_q is None:
                Q[:, 6] = 1.0
            else:
                Q[:, :7] = base_q
        for i, name in enumerate(self.joint_names):
            iq = self.q_index(name)
            if self.is_continuous(name):
                Q[:, iq] = np.cos(q_joints[:, i])
                Q[:, iq + 1] = np.sin(q_joints[:, i])
            else:
                Q[:, iq] = q_joints[:, i]
        return Q

    def full_velocity(self, v_joints: np.ndarray, base_v: np.ndarray | None = None) -> np.ndarray:
        """Pinocchio velocities/accelerations (N, nv) from joint values in ``joint_names`` order."""
        v_joints = np.atleast_2d(v_joints)
        V = np.zeros((v_joints.shape[0], self.nv))
        if self.floating_base and base_v is not None:
            V[:, :6] = base_v
        idx = [self.v_index(n) for n in self.joint_names]
        V[:, idx] = v_joints
        return V

    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper position limits of ``joint_names`` (inf where unlimited, also for
        Pinocchio's "no limit" ±float max of a joint added without limits)."""
        lo, hi = [], []
        for n in self.joint_names:
            iq = self.q_index(n)
            if self.is_continuous(n):
                lo.append(-np.inf)
                hi.append(np.inf)
            else:
                lo.append(self.model.lowerPositionLimit[iq])
                hi.append(self.model.upperPositionLimit[iq])
        big = np.finfo(float).max
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        return np.where(lo <= -big, -np.inf, lo), np.where(hi >= big, np.inf, hi)

    def velocity_limits(self) -> np.ndarray:
        return np.array([self.model.velocityLimit[self.v_index(n)] for n in self.joint_names])

    def is_revolute(self, joint: str) -> bool:
        short = self.model.joints[self.joint_id(joint)].shortname()
        return "JointModelR" in short  # RX/RY/RZ, RevoluteUnaligned, RUB* (continuous)

    def summary(self) -> dict:
        return {
            "name": self.name,
            "source": self.source,
            "floating_base": self.floating_base,
            "nq": self.nq,
            "nv": self.nv,
            "bodies": list(self.body_names),
            "actuated_joints": list(self.actuated_joints),
            **({"passive_joints": list(self.passive_joints)} if self.passive_joints else {}),
            "total_mass": float(sum(self.model.inertias[j].mass for j in range(1, self.model.njoints))),
            "kinematics": kinematics_summary(self.model),
        }


def kinematics_table(model: pin.Model) -> list[list]:
    """The kinematic tree of ``model`` as plain data, one row per joint below the universe:
    ``[name, type, parent name, x, y, z, R00, R01, …, R22]`` (the joint's placement in its parent;
    the type is Pinocchio's short name, with the axis for an unaligned joint)."""
    rows = []
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = joint.shortname()
        if "Unaligned" in kind:
            kind += "(" + ",".join(f"{a:.9g}" for a in joint.extract().axis) + ")"
        M = model.jointPlacements[j]
        numbers = np.concatenate([M.translation, M.rotation.reshape(-1)])
        rows.append([model.names[j], kind, model.names[model.parents[j]],
                     *(float(round(x, 9)) + 0.0 for x in numbers)])
    return rows


def kinematics_fingerprint(table: list[list]) -> str:
    """A short hash of a :func:`kinematics_table` (names, types, parents, placements to 0.1 mm): equal
    fingerprints are the same robot; unequal ones are compared with :func:`kinematics_difference`."""
    import hashlib

    text = ";".join(",".join(str(x) if isinstance(x, str) else f"{round(x, 4) + 0.0:.4f}" for x in row)
                    for row in table)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def kinematics_summary(model: pin.Model) -> dict:
    """``{"fingerprint", "joints"}`` of ``model``: what a model artifact stores of its robot."""
    table = kinematics_table(model)
    return {"fingerprint": kinematics_fingerprint(table), "joints": table}


def kinematics_difference(stored: list[list], table: list[list], tol: float = KINEMATICS_TOL) -> str | None:
    """The first difference of the robot given (``table``) from a model's robot (``stored``), both
    :func:`kinematics_table` s, in words; None when they are the same robot."""
    names, ours = [r[0] for r in stored], [r[0] for r in table]
    if names != ours:
        missing, extra = [n for n in names if n not in ours], [n for n in ours if n not in names]
        if missing:
            return f"the robot given has no joint(s) {missing[:3]}{' …' if len(missing) > 3 else ''}"
        if extra:
            return f"the robot given has joint(s) {extra[:3]}{' …' if len(extra) > 3 else ''} the model's has not"
        return "the same joints in another order"
    for a, b in zip(stored, table):
        if a[1] != b[1]:
            return f"joint '{a[0]}' is {b[1].replace('JointModel', '')} in the robot given, {a[1].replace('JointModel', '')} in the model's"
        if a[2] != b[2]:
            return f"joint '{a[0]}' hangs from '{b[2]}' in the robot given, from '{a[2]}' in the model's"
        dt = float(np.linalg.norm(np.subtract(a[3:6], b[3:6], dtype=float)))
        dr = float(np.max(np.abs(np.subtract(a[6:], b[6:], dtype=float))))
        if dt > tol:
            return f"joint '{a[0]}' is {dt:.3g} m from its place in the model's robot"
        if dr > tol:
            return f"joint '{a[0]}' is turned from its orientation in the model's robot"
    return None


#: file suffixes of a robot description (anything else is looked up in the registry)
MODEL_SUFFIXES = (".urdf", ".xml", ".mjcf", ".xacro")


def _build(spec: str, floating_base: bool | None, trust_xacro: bool = False,
           packages: Sequence[Path] = ()) -> tuple[pin.Model, str, str, str | None]:
    """(model, name, source, URDF path or None) of a model file or an example-robot-data name.
    A xacro file is refused unless ``trust_xacro`` (nothing of it is read); MJCF files naming
    files outside their folder and ``packages`` are refused (:mod:`.robot_paths`)."""
    path = Path(spec)
    suffix = path.suffix.lower()
    if suffix == ".xacro":
        if not path.is_file():
            raise RobotModelError(f"{spec}: no such robot model file")
        model, _, _, urdf = _build(str(expand_xacro(path, trusted=trust_xacro)), floating_base)
        return model, path.name.split(".")[0], str(path), urdf
    if suffix in {".urdf", ".xml", ".mjcf"}:
        if not path.exists():
            raise RobotModelError(f"{spec}: no such robot model file")
        from .model_checks import check_mjcf_file, check_model, check_urdf_file, quiet_stderr

        if not path.is_file():
            raise RobotModelError(f"{spec}: not a regular file")
        size = path.stat().st_size
        if size > MAX_DESCRIPTION_BYTES:
            raise RobotModelError(f"{spec}: a robot description of {size} bytes is larger than the limit of "
                                  f"{MAX_DESCRIPTION_BYTES} bytes")
        if suffix == ".urdf":
            check_urdf_file(path)  # one-line errors for malformed XML and impossible values
        else:
            from .robot_paths import check_mjcf_paths

            check_mjcf_paths(path, packages)  # includes and assets stay in the allowed folders
            check_mjcf_file(path)  # negative masses/inertias, which Pinocchio clamps to 0
        def parse():
            if suffix != ".urdf":
                return pin.buildModelFromMJCF(str(path))
            if floating_base:
                return pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
            return pin.buildModelFromUrdf(str(path))

        parse_in_child(parse, spec)  # a parser crash (a segfault on a deep chain) is a typed error here
        captured: list[str] = []
        try:
            with quiet_stderr() as captured:  # urdfdom/MuJoCo print multi-line C++ messages on fd 2
                model = parse()
        except Exception as exc:  # Pinocchio raises bare RuntimeError/ValueError
            detail = " ".join(" ".join(str(exc).split()).split(" | ")) or type(exc).__name__
            extra = f" [{' / '.join(captured[:3])[:300]}]" if captured else ""
            raise RobotModelError(f"{spec}: Pinocchio could not parse the model: {detail[:400]}{extra}") from None
        check_model(model, str(path))
        return model, path.stem, str(path), str(path) if suffix == ".urdf" else None
    entry = find_robot(spec)
    if entry is None:
        known = robot_names()
        hint = did_you_mean(spec, known)
        hint = hint + " " if hint else ""
        raise RobotModelError(
            f"'{spec}': neither a .urdf/.xacro/.xml file nor a registered robot name; {hint}"
            f"(known names: {', '.join(known)})"
        )
    return entry.load(spec, floating_base)


#: largest robot description file read [bytes] (a URDF with inline meshes stays far below)
MAX_DESCRIPTION_BYTES = 32 * 1024 * 1024
#: seconds a description may take to parse in the child before it is a RobotModelError
PARSE_TIMEOUT = 120.0


def parse_in_child(parse, spec: str, timeout: float = PARSE_TIMEOUT) -> None:
    """Run ``parse()`` in a forked child first: a crash of the C++ parser (a segfault, an abort) or a
    parse running past ``timeout`` is a RobotModelError naming ``spec`` instead of killing this
    process. Where fork is unavailable nothing is checked (the parse runs in-process only)."""
    import signal
    import time

    if not hasattr(os, "fork"):
        return
    pid = os.fork()
    if pid == 0:  # the child: parse, report by the exit status only
        code = 0
        try:
            import faulthandler

            faulthandler.disable()  # the crash is the parent's to report, in one line
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 2)
            parse()
        except BaseException:  # a Python exception is the in-process parse's to report
            code = 0
        os._exit(code)
    deadline = time.monotonic() + timeout
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise RobotModelError(f"{spec}: parsing the robot description took more than {timeout:g} s; refused")
        time.sleep(0.005)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else str(sig)
        raise RobotModelError(f"{spec}: the robot description parser crashed ({name}) on this file (a very deep "
                              "or malformed kinematic tree?); refused")


def load_robot(
    spec: str | Path,
    *,
    floating_base: bool | None = None,
    lock_joints: Sequence[str] = (),
    actuated_joints: Sequence[str] | None = None,
    passive_joints: Sequence[str] = (),
    armature: dict[str, float] | None = None,
    trust_xacro: bool = False,
    package_paths: Sequence[str | Path] = (),
) -> Robot:
    """Load a robot from a URDF path, a xacro file (with ``trust_xacro=True`` only: it can run code),
    an MJCF path or a name of the robot registry (:mod:`sensorless.robots.registry`: example-robot-data's
    catalogue; a robot built in code, such as ``dvrk_psm``, is returned as built, and the options below
    do not apply to it).

    ``lock_joints`` are fixed at their neutral position (e.g. a gripper's fingers).
    ``passive_joints`` have no actuator (a rail, a free pivot): no torque is measured there, their
    generalized force is zero apart from their own friction. ``actuated_joints`` defaults to every
    other 1-DoF joint. ``armature`` sets rotor inertia
    per joint name when the model file has none.

    A xacro file can run code when expanded: it is refused (UntrustedModelError) unless
    ``trust_xacro=True``, and then expanded in a subprocess with time and memory limits.
    Files the description names (meshes, ``package://``, MJCF includes) are followed only under
    its own folder and ``package_paths`` (plus ``ROS_PACKAGE_PATH``; :mod:`sensorless.robot_paths`).
    """
    from .robot_paths import package_roots

    entry = None if Path(str(spec)).suffix.lower() in MODEL_SUFFIXES else find_robot(str(spec))
    if entry is not None and entry.in_code:
        given = [name for name, value in (("floating_base", floating_base), ("lock_joints", lock_joints),
                                          ("actuated_joints", actuated_joints), ("passive_joints", passive_joints),
                                          ("armature", armature)) if value]
        if given:
            raise RobotModelError(f"'{spec}' is {entry.description}, built in code: it does not take "
                                  f"{', '.join(setting(g) for g in given)}")
        return entry.load(str(spec))
    packages = package_roots(package_paths)
    model, name, source, urdf = _build(str(spec), floating_base, trust_xacro, packages)
    if lock_joints:
        # some example-robot-data models set lowerVelocityLimit = +max, which buildReducedModel rejects
        model.lowerVelocityLimit = -np.abs(model.upperVelocityLimit)
        names = list(model.names)
        bad = [j for j in lock_joints if j not in names]
        if bad:
            raise RobotModelError(f"{source}: cannot lock unknown joint(s) {bad}{_hint(bad, names[1:])}; "
                                  f"known: {names[1:]}")
        ids = [names.index(j) for j in lock_joints]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    locked = [j for j in passive_joints if j in lock_joints]
    if locked:
        raise RobotModelError(f"{source}: joint(s) {locked} cannot be both locked and passive")
    robot = Robot(model, name=name, source=source, actuated_joints=tuple(actuated_joints or ()),
                  passive_joints=tuple(passive_joints))
    robot.locked_joints = tuple(lock_joints)
    robot.added_frames = []
    robot.urdf_path = urdf
    robot.package_paths = packages
    robot.description_dir = None if source.startswith("example-robot-data:") else str(Path(source).parent)
    if armature:
        for j, val in armature.items():
            robot.model.armature[robot.v_index(j)] = float(val)
    return robot


def add_frame(robot, name: str, parent: str, xyz: Sequence[float], rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> int:
    """Add an operational frame ``name`` at ``xyz`` [m] and roll-pitch-yaw ``rpy`` [rad] in the
    axes of frame ``parent`` (any frame of the model: a link, a joint, another frame) and
    return its id. Works on a :class:`Robot` and on a coordinate robot (the frame goes on its
    tree); the robot's Pinocchio data is recreated. RobotModelError names the frame or parent."""
    base = getattr(robot, "tree", robot)
    model = base.model
    label = getattr(robot, "source", "") or getattr(robot, "name", "robot")
    xyz, rpy = np.asarray(xyz, float).reshape(-1), np.asarray(rpy, float).reshape(-1)
    if not name or any(c in name for c in ":,") or not name.strip() == name:
        raise RobotModelError(f"{label}: cannot add a frame named '{name}': give a name without ':', ',' or spaces around it")
    if model.existFrame(name):
        raise RobotModelError(f"{label}: cannot add frame '{name}': the model already has a frame of that name")
    if not model.existFrame(parent):
        frames = [f.name for f in model.frames]
        raise RobotModelError(f"{label}: cannot add frame '{name}': unknown parent frame '{parent}'"
                              f"{_hint([parent], frames)}; known frames: {frames}")
    if xyz.shape != (3,) or rpy.shape != (3,) or not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(rpy))):
        raise RobotModelError(f"{label}: frame '{name}' needs a finite position x,y,z and rotation r,p,y, "
                              f"got {xyz.tolist()} and {rpy.tolist()}")
    pid = model.getFrameId(parent)
    pf = model.frames[pid]
    placement = pf.placement * pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)
    fid = model.addFrame(pin.Frame(name, pf.parentJoint, pid, placement, pin.FrameType.OP_FRAME))
    base.data = model.createData()
    added = getattr(robot, "added_frames", None)
    if isinstance(added, list):  # recorded in a model folder (settings.robot.frames)
        added.append([name, parent, xyz.tolist(), rpy.tolist()])
    return int(fid)


def frame_table(robot) -> list[dict]:
    """Every frame of ``robot`` (of its tree for a coordinate robot): name, type, parent joint
    and frame, placement in the parent joint's axes, and world origin and axes (columns x, y,
    z of the rotation) at zero joint values."""
    base = getattr(robot, "tree", robot)
    model = base.model
    data = model.createData()
    zero = np.zeros((1, len(robot.joint_names)))
    q = (robot.tree_state(zero)[0] if base is not robot else robot.full_configuration(zero))[0]
    pin.framesForwardKinematics(model, data, q)
    out = []
    for k, f in enumerate(model.frames):
        w = data.oMf[k]
        out.append({
            "name": f.name, "type": str(f.type).split(".")[-1], "parent_joint": model.names[f.parentJoint],
            "parent_frame": model.frames[f.parentFrame].name if k else "",
            "xyz": f.placement.translation.tolist(), "rpy": pin.rpy.matrixToRpy(f.placement.rotation).tolist(),
            "world_origin": w.translation.tolist(), "world_axes": w.rotation.T.tolist(),
        })
    return out


def _hint(unknown: Sequence[str], known: Sequence[str]) -> str:
    """"; for 'x', did you mean 'y'?" for each unknown name with a close known one (:func:`did_you_mean`)."""
    parts = [(n, did_you_mean(n, known)) for n in unknown]
    parts = [(n, h) for n, h in parts if h]
    if len(parts) == 1 and len(unknown) == 1:
        return f" ({parts[0][1]})"
    return "".join(f"; for '{n}', {h}" for n, h in parts)

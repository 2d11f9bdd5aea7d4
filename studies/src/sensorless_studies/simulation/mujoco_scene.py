"""MuJoCo scenes built programmatically from a :class:`~sensorless.robot.Robot` (a floating base, or a
fixed base whose unactuated "base" is a passive joint, e.g. a leg on a vertical rail).

The MuJoCo model is written body by body from the Pinocchio model with ``mujoco.MjSpec``
(no URDF/mesh round trip), so its inertial parameters are those of the Pinocchio model
exactly: one MuJoCo body per Pinocchio joint, placed at ``model.jointPlacements[j]``, with
mass, CoM ``lever`` and rotational inertia about the CoM (``fullinertia``) copied from
``model.inertias[j]``; geoms carry no inertia (``inertiafromgeom = false``).

Added to the kinematic tree:

* a free joint on the root body of a floating base, a ground plane (``z = 0``) and a collision sphere
  at each foot frame (feet collide with the ground only; nothing else collides);
* a torque motor per actuated joint (``gear = 1``, ``ctrlrange = ±torque_limit``), none on a passive
  joint (``robot.passive_joints``), which only has its friction;
* joint armature ``Ia``, viscous damping ``fv`` and Coulomb friction loss ``fc``, so the
  actuated-joint dynamics is

      M(q) v̇ + h(q, v) = Sᵀ(τ − fv v − fc sgn v) + Jcᵀ f,     M includes diag(Ia),

  with MuJoCo's friction loss a (soft) constraint: saturated at ±fc except at small joint
  speeds, where it is a stiff regularised (stiction-like) Coulomb law.

State conventions (converted by :func:`mj_to_pin_state` / :func:`pin_to_mj_state`):

=============  ======================================  ===========================================
               MuJoCo free joint                       Pinocchio free flyer
=============  ======================================  ===========================================
position       ``qpos[:7] = [x y z qw qx qy qz]``      ``q[:7] = [x y z qx qy qz qw]``
velocity       ``qvel[:6] = [ṗ (world); ω (body)]``    ``v[:6] = [Rᵀṗ; ω]`` (LOCAL)
acceleration   ``qacc[:6] = [p̈ (world); ω̇ (body)]``  ``a[:6] = [Rᵀp̈ − ω × Rᵀṗ; ω̇]``
=============  ======================================  ===========================================
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from sensorless.errors import RobotModelError, ShapeMismatchError, setting
from sensorless.robot import Robot

__all__ = [
    "MujocoScene",
    "build_scene",
    "default_foot_frames",
    "mj_to_pin_state",
    "pin_to_mj_state",
    "quat_to_matrix",
]

_PRISMATIC = {"JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"}


def default_foot_frames(robot: Robot) -> tuple[str, ...]:
    """Frames named ``*_FOOT`` (Solo12: FL, FR, HL, HR), in model order."""
    feet = tuple(f.name for f in robot.model.frames if f.name.endswith("_FOOT"))
    if not feet:
        raise RobotModelError(
            f"{robot.source or robot.name}: no frame named '*_FOOT'; give them: {setting('foot_frames', placeholder='(...)')}"
        )
    return feet


def quat_to_matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) from unit quaternions (..., 4) ordered ``[x y z w]`` (SciPy)."""
    q = np.asarray(quat_xyzw, dtype=float)
    return Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))


@dataclass
class MujocoScene:
    """A compiled MuJoCo model of ``robot`` plus the index maps between the two libraries.

    ``robot`` is the Pinocchio model the scene was built from (the simulation's truth).
    Per-joint arrays (``armature``, ``torque_limit``) are in ``robot.actuated_joints`` order, ``fv``
    and ``fc`` in ``robot.term_joints`` order (actuated, then passive); actuator ``k`` drives
    ``robot.actuated_joints[k]``.
    """

    robot: Robot
    model: mujoco.MjModel = field(repr=False)
    spec: mujoco.MjSpec = field(repr=False)
    foot_frames: tuple[str, ...]
    foot_radius: float
    fv: np.ndarray
    fc: np.ndarray
    armature: np.ndarray
    torque_limit: np.ndarray
    qpos_adr: np.ndarray = field(repr=False)  # per robot.joint_names
    dof_adr: np.ndarray = field(repr=False)  # per robot.joint_names
    act_dof_adr: np.ndarray = field(repr=False)  # per robot.actuated_joints
    term_dof_adr: np.ndarray = field(repr=False)  # per robot.term_joints (actuated, then passive)
    foot_geoms: np.ndarray = field(repr=False)  # per foot_frames
    floor_geom: int = 0
    base_body: int = 1
    coulomb_velocity: float = 0.0  # > 0: Coulomb friction applied as −fc tanh(v/ε) (see build_scene)

    @property
    def n_feet(self) -> int:
        return len(self.foot_frames)

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def make_data(self) -> mujoco.MjData:
        return mujoco.MjData(self.model)

    def set_state(self, data: mujoco.MjData, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """Write one Pinocchio state (full ``q``, ``v``) into ``data`` and run ``mj_forward``."""
        qpos, qvel, _ = pin_to_mj_state(self, q[None], None if v is None else v[None])
        data.qpos[:] = qpos[0]
        data.qvel[:] = 0.0 if v is None else qvel[0]
        mujoco.mj_forward(self.model, data)

    def foot_contacts(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Per foot: contact flag (any foot–floor contact) and the total force (world frame)
        the floor exerts on the foot, shape (n_feet,) and (n_feet, 3)."""
        flags = np.zeros(self.n_feet, dtype=bool)
        forces = np.zeros((self.n_feet, 3))
        buf = np.zeros(6)
        geoms = self.foot_geoms
        for i in range(data.ncon):
            c = data.contact[i]
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            if g2 in geoms:
                k, sign = int(np.flatnonzero(geoms == g2)[0]), 1.0  # force of geom1 on geom2
            elif g1 in geoms:
                k, sign = int(np.flatnonzero(geoms == g1)[0]), -1.0
            else:
                continue
            flags[k] = True
            mujoco.mj_contactForce(self.model, data, i, buf)
            forces[k] += sign * (c.frame.reshape(3, 3).T @ buf[:3])
        return flags, forces

    def apply_coulomb(self, data: mujoco.MjData) -> None:
        """With ``coulomb_velocity`` ε > 0, write −fc tanh(v/ε) of the current velocities into
        ``qfrc_applied`` (call after ``mj_step1``, before ``mj_step2``); a no-op otherwise."""
        if self.coulomb_velocity > 0:
            v = data.qvel[self.term_dof_adr]
            data.qfrc_applied[self.term_dof_adr] = -self.fc * np.tanh(v / self.coulomb_velocity)

    def joint_friction(self, data: mujoco.MjData) -> np.ndarray:
        """Friction torque the joints actually receive, −(fv v + Coulomb/friction-loss force), per
        term joint (actuated, then passive; valid after the acceleration stage: ``mj_step2`` / ``mj_forward``)."""
        if self.coulomb_velocity > 0:
            return data.qfrc_damper[self.term_dof_adr] + data.qfrc_applied[self.term_dof_adr]
        fl = np.zeros(self.model.nv)
        rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        if np.any(rows):
            fl[data.efc_id[rows]] = data.efc_force[rows]
        return data.qfrc_damper[self.term_dof_adr] + fl[self.term_dof_adr]

    def foot_positions(self, data: mujoco.MjData) -> np.ndarray:
        """World positions of the foot-sphere centres (n_feet, 3)."""
        return data.geom_xpos[self.foot_geoms].copy()


def build_scene(
    robot: Robot,
    *,
    fv: np.ndarray | float = 0.0,
    fc: np.ndarray | float = 0.0,
    armature: np.ndarray | float | None = None,
    foot_frames: Sequence[str] | None = None,
    foot_radius: float = 0.016,
    torque_limit: np.ndarray | float | None = None,
    timestep: float = 1e-3,
    ground_friction: float = 1.0,
    contact_solref: tuple[float, float] = (0.005, 1.0),
    contact_solimp: tuple[float, ...] = (0.9, 0.95, 0.001, 0.5, 2.0),
    integrator: str = "euler",
    joint_limits: bool = False,
    friction_timeconst: float | None = None,
    coulomb_velocity: float = 0.0,
) -> MujocoScene:
    """Build and compile a MuJoCo scene whose rigid-body model equals ``robot``'s.

    ``robot`` has a free-flyer root, or a fixed base (its first joint is then attached to the world:
    a passive rail carrying a leg). ``fv``, ``fc`` (scalar, per actuated joint, or per term joint:
    actuated then passive) and ``armature`` (scalar or per actuated joint; ``None`` takes
    ``robot.armature``) become the MuJoCo joints' ``damping``, ``frictionloss`` and ``armature``. ``torque_limit`` defaults to the
    model's effort limits. ``joint_limits=False`` leaves joints unlimited (a limit
    force would be an unlogged torque). ``foot_radius`` is the collision-sphere radius
    centred on each foot frame (Solo12's foot: 0.016 m).

    MuJoCo's friction loss is a soft constraint whose reference acceleration is about
    −v/T_f: it equals −fc sgn(v) once the force needed to stop the joint within ``T_f``
    exceeds fc, and takes values in [−fc, fc] below that (stiction-like).
    ``friction_timeconst`` T_f defaults to two time steps (the stiffest stable choice);
    for Solo12 at 1 kHz the law is Coulomb's above about 0.1 rad/s.

    ``coulomb_velocity`` ε > 0 replaces the friction loss by the smooth law −fc tanh(v/ε),
    applied explicitly each step by :meth:`MujocoScene.apply_coulomb` (no stiction): the
    friction model of the identification (``coulomb_smoothing``), so that a study can
    separate identification error from friction-model mismatch. Explicit integration needs
    fc·dt/(ε·I) < 2 for the smallest joint inertia I: ε ≈ 0.03 rad/s for Solo12 at 1 kHz.
    """
    if coulomb_velocity < 0:
        raise RobotModelError(f"coulomb_velocity must be ≥ 0, got {coulomb_velocity}")
    pm = robot.model
    if robot.floating_base and not pm.jointPlacements[1].isIdentity():
        raise RobotModelError(f"{robot.source or robot.name}: the free-flyer placement must be the identity")
    feet = tuple(foot_frames) if foot_frames is not None else default_foot_frames(robot)
    for f in feet:
        robot.frame_id(f)  # RobotModelError naming the frame
    n_act, terms = robot.n_actuated, tuple(robot.term_joints)

    def per_joint(x, name, n=n_act):
        arr = np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy() if np.ndim(x) == 0 else np.asarray(x, float)
        if n != n_act and arr.shape == (n_act,):  # friction given for the actuated joints: passive ones without
            arr = np.concatenate([arr, np.zeros(n - n_act)])
        if arr.shape != (n,):
            raise ShapeMismatchError(f"{name} has shape {arr.shape}; expected ({n},) (one per "
                                     f"{'actuated' if n == n_act else 'actuated or passive'} joint)")
        return arr

    fv = per_joint(fv, "fv", len(terms))
    fc = per_joint(fc, "fc", len(terms))
    arm = robot.armature if armature is None else per_joint(armature, "armature")
    eff = np.array([pm.effortLimit[robot.v_index(j)] for j in robot.actuated_joints])
    lim = per_joint(eff if torque_limit is None else torque_limit, "torque_limit")
    lim = np.where(np.isfinite(lim) & (lim > 0), lim, 1e6)

    spec = mujoco.MjSpec()
    spec.modelname = f"{robot.name}_scene"
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.balanceinertia = False
    spec.compiler.boundmass = 0.0
    spec.compiler.boundinertia = 0.0
    spec.compiler.autolimits = False
    opt = spec.option
    opt.timestep = float(timestep)
    integrators = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
    if integrator not in integrators:
        raise RobotModelError(f"integrator must be one of {sorted(integrators)}, got {integrator!r}")
    opt.integrator = integrators[integrator]
    opt.gravity = np.asarray(pm.gravity.linear, dtype=float)

    floor = spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05], contype=0, conaffinity=1
    )
    floor.friction = [ground_friction, 0.005, 0.0001]

    bodies: dict[int, mujoco.MjsBody] = {0: spec.worldbody}
    arm_by_joint = dict(zip(robot.actuated_joints, arm))
    fv_by_joint = dict(zip(terms, fv))
    fc_by_joint = dict(zip(terms, fc))
    for j in range(1, pm.njoints):
        M = pm.jointPlacements[j]
        quat = pin.Quaternion(M.rotation).coeffs()  # x y z w
        name = pm.names[j]
        body = bodies[pm.parents[j]].add_body(
            name=name, pos=M.translation.copy(), quat=[quat[3], quat[0], quat[1], quat[2]]
        )
        I = pm.inertias[j]
        body.mass = float(I.mass)
        body.ipos = np.asarray(I.lever, dtype=float).copy()
        Ic = np.asarray(I.inertia)
        body.fullinertia = [Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]
        body.explicitinertial = True
        bodies[j] = body
        if j == 1 and robot.floating_base:
            body.add_freejoint(name=name)
            continue
        jm = pm.joints[j]
        jd = jm.createData()
        jm.calc(jd, pin.neutral(pm))
        S = np.asarray(jd.S).reshape(6)
        prismatic = jm.shortname() in _PRISMATIC
        jnt = body.add_joint(
            name=name,
            type=mujoco.mjtJoint.mjJNT_SLIDE if prismatic else mujoco.mjtJoint.mjJNT_HINGE,
            axis=(S[:3] if prismatic else S[3:]).copy(),
        )
        jnt.armature = float(arm_by_joint.get(name, pm.armature[jm.idx_v]))
        jnt.damping = [float(fv_by_joint.get(name, 0.0)), 0.0, 0.0]  # MuJoCo 4: polynomial damping
        jnt.frictionloss = 0.0 if coulomb_velocity > 0 else float(fc_by_joint.get(name, 0.0))
        jnt.solref_friction = [friction_timeconst or 2.0 * timestep, 1.0]
        jnt.solimp_friction = [0.99, 0.999, 0.001, 0.5, 2.0]
        iq = jm.idx_q
        if joint_limits and jm.nq == 1 and np.isfinite(pm.lowerPositionLimit[iq]) and pm.upperPositionLimit[iq] < 1e10:
            jnt.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            jnt.range = [pm.lowerPositionLimit[iq], pm.upperPositionLimit[iq]]
        else:
            jnt.limited = mujoco.mjtLimited.mjLIMITED_FALSE

    for k, jname in enumerate(robot.actuated_joints):
        act = spec.add_actuator(name=jname, target=jname, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        act.gear[0] = 1.0
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [-lim[k], lim[k]]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE

    for f in feet:
        fr = pm.frames[robot.frame_id(f)]
        geom = bodies[fr.parentJoint].add_geom(
            name=f,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[foot_radius, 0.0, 0.0],
            pos=np.asarray(fr.placement.translation, dtype=float).copy(),
            contype=1,
            conaffinity=0,
            condim=3,
        )
        geom.friction = [ground_friction, 0.005, 0.0001]
        geom.solref = list(contact_solref)
        geom.solimp = list(contact_solimp)
    try:
        model = spec.compile()
    except ValueError as exc:  # MuJoCo reports compiler errors as ValueError
        raise RobotModelError(f"{robot.source or robot.name}: MuJoCo could not compile the scene: {exc}") from None

    jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in robot.joint_names]
    act_jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in robot.actuated_joints]
    term_jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in terms]
    return MujocoScene(
        robot=robot,
        model=model,
        spec=spec,
        foot_frames=feet,
        foot_radius=float(foot_radius),
        fv=fv,
        fc=fc,
        armature=np.asarray(arm, dtype=float).copy(),
        torque_limit=lim,
        qpos_adr=np.asarray(model.jnt_qposadr[jid], dtype=int),
        dof_adr=np.asarray(model.jnt_dofadr[jid], dtype=int),
        act_dof_adr=np.asarray(model.jnt_dofadr[act_jid], dtype=int),
        term_dof_adr=np.asarray(model.jnt_dofadr[term_jid], dtype=int),
        foot_geoms=np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f) for f in feet], dtype=int),
        floor_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor"),
        base_body=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, pm.names[1]),
        coulomb_velocity=float(coulomb_velocity),
    )


def _as2d(x: np.ndarray | None, n: int, name: str) -> np.ndarray | None:
    if x is None:
        return None
    x = np.asarray(x, dtype=float)
    x = x[None] if x.ndim == 1 else x
    if x.ndim != 2 or x.shape[1] != n:
        raise ShapeMismatchError(f"{name} must have {n} columns, got shape {x.shape}")
    return x


def mj_to_pin_state(
    scene: MujocoScene, qpos: np.ndarray, qvel: np.ndarray | None = None, qacc: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """MuJoCo ``(qpos, qvel, qacc)`` → Pinocchio full ``(q, v, a)``, batched over rows (N, ·).

    Base: quaternion ``wxyz → xyzw``; ``v_lin = Rᵀ ṗ``; ``a_lin = Rᵀ p̈ − ω × v_lin``.
    Joints are gathered by name into Pinocchio's layout (continuous joints as cos/sin).
    """
    m, r = scene.model, scene.robot
    qpos = _as2d(qpos, m.nq, "qpos")
    qvel = _as2d(qvel, m.nv, "qvel")
    qacc = _as2d(qacc, m.nv, "qacc")
    if not r.floating_base:  # a fixed base: the joints only
        Q = r.full_configuration(qpos[:, scene.qpos_adr])
        V = None if qvel is None else r.full_velocity(qvel[:, scene.dof_adr])
        A = None if qacc is None or qvel is None else r.full_velocity(qacc[:, scene.dof_adr])
        return Q, V, A
    base_q = np.concatenate([qpos[:, :3], qpos[:, 4:7], qpos[:, 3:4]], axis=1)
    Q = r.full_configuration(qpos[:, scene.qpos_adr], base_q)
    if qvel is None:
        return Q, None, None
    R = quat_to_matrix(base_q[:, 3:])
    v_lin = np.einsum("nji,nj->ni", R, qvel[:, :3])
    w = qvel[:, 3:6]
    V = r.full_velocity(qvel[:, scene.dof_adr], np.concatenate([v_lin, w], axis=1))
    if qacc is None:
        return Q, V, None
    a_lin = np.einsum("nji,nj->ni", R, qacc[:, :3]) - np.cross(w, v_lin)
    A = r.full_velocity(qacc[:, scene.dof_adr], np.concatenate([a_lin, qacc[:, 3:6]], axis=1))
    return Q, V, A


def pin_to_mj_state(
    scene: MujocoScene, q: np.ndarray, v: np.ndarray | None = None, a: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Pinocchio full ``(q, v, a)`` → MuJoCo ``(qpos, qvel, qacc)``, batched (inverse of
    :func:`mj_to_pin_state`)."""
    m, r = scene.model, scene.robot
    q = _as2d(q, r.nq, "q")
    v = _as2d(v, r.nv, "v")
    a = _as2d(a, r.nv, "a")
    N = q.shape[0]
    qpos = np.zeros((N, m.nq))
    if r.floating_base:
        qpos[:, :3] = q[:, :3]
        qpos[:, 3] = q[:, 6]
        qpos[:, 4:7] = q[:, 3:6]
    for k, name in enumerate(r.joint_names):
        iq = r.q_index(name)
        qpos[:, scene.qpos_adr[k]] = np.arctan2(q[:, iq + 1], q[:, iq]) if r.is_continuous(name) else q[:, iq]
    if v is None:
        return qpos, None, None
    if not r.floating_base:
        vidx = [r.v_index(n) for n in r.joint_names]
        qvel, qacc = np.zeros((N, m.nv)), None if a is None else np.zeros((N, m.nv))
        qvel[:, scene.dof_adr] = v[:, vidx]
        if a is not None:
            qacc[:, scene.dof_adr] = a[:, vidx]
        return qpos, qvel, qacc
    R = quat_to_matrix(q[:, 3:7])
    vidx = [r.v_index(n) for n in r.joint_names]
    qvel = np.zeros((N, m.nv))
    qvel[:, :3] = np.einsum("nij,nj->ni", R, v[:, :3])
    qvel[:, 3:6] = v[:, 3:6]
    qvel[:, scene.dof_adr] = v[:, vidx]
    if a is None:
        return qpos, qvel, None
    qacc = np.zeros((N, m.nv))
    qacc[:, :3] = np.einsum("nij,nj->ni", R, a[:, :3] + np.cross(v[:, 3:6], v[:, :3]))
    qacc[:, 3:6] = a[:, 3:6]
    qacc[:, scene.dof_adr] = a[:, vidx]
    return qpos, qvel, qacc

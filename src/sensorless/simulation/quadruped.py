"""Simulated quadruped logs with ground truth: scenarios, a whole-body controller, noise.

:func:`simulate` runs one scenario in MuJoCo (:mod:`.mujoco_scene`) and returns what a
user's logger would record (a :class:`~sensorless.data.Trajectory`) and, separately, what
only the simulation knows (:class:`SimulationTruth`).

Simulated robot
    The "true" robot is ``make_truth(nominal, truth_seed)``: the nominal model with every
    body's mass, CoM and inertia perturbed (:func:`~.synthetic.perturbed_truth`), joint
    viscous friction ``fv``, Coulomb friction ``fc`` and armature drawn in the robot
    profile's ranges, torque offset 0. MuJoCo's model equals it exactly.

Controller (uses the *nominal* model, as a real controller would)
    The scenario is a plan: base pose ``(p, R)(t)``, world foot positions and planned
    stance flags, sampled at the control rate. Joint references ``q*`` come from leg
    inverse kinematics of the feet relative to the planned base. Each control step
    (default 1 kHz, = the simulation step):

        v̇*_b = base PD on (p, R) towards the plan (world frame, mapped to LOCAL),
        τ_full = M(q) [v̇*_b; q̈*] + h(q, v),
        f = argmin ‖J_c,bᵀ f − τ_full,b‖² + λ‖f‖²   (stance feet, then f_z ≥ 0, |f_t| ≤ μ f_z),
        τ = τ_full,j − J_c,jᵀ f + Kp (q* − q) + Kd (q̇* − q̇),   clipped to the torque limit.

    With no foot in stance the base rows use the free-fall acceleration
    ``v̇_b = −M_bb⁻¹(M_bj q̈* + h_b)``.

Scenarios (:data:`SCENARIOS` in :mod:`.quadruped_plans`; randomised by ``seed``; robot
settings in :mod:`.quadruped_profiles`)
    ``wobble``  all four feet fixed; base height/roll/pitch/yaw (and a little x, y) follow
               sums of two sines with random amplitudes, frequencies and phases.
    ``trot``    diagonal pairs alternate at ``speed`` m/s (duty 0.55, footholds under the
               hips at mid-stance), with a small random base wobble on top.
    ``crawl``   one foot at a time (HL, FL, HR, FR), the base shifting over the
               support triangle before each step.
    ``jump``    stand, crouch, push off with all legs, flight, landing, repeated; the plan
               is re-timed at the actual touchdown.

Logging (default 100 Hz, every ``sim_rate / log_rate`` steps; q, v, τ, f of the same instant)
    ``q``, ``v`` joint encoders (+ noise), ``a = None`` (estimate it from ``q`` or ``v``,
    e.g. :func:`~sensorless.data.savgol_derivatives`), ``tau`` = MuJoCo actuator force
    (+ noise; the measured motor torque), ``base_q`` (+ small pose noise), ``base_v``
    (LOCAL twist + noise), ``base_a = None``, ``extras["contact"]`` (N, n_feet) bool,
    ``extras["foot_height"]`` (N, n_feet) height of each foot sphere's bottom [m],
    ``extras["imu_acc"]`` (N, 3) accelerometer at the base origin (specific force, base
    frame, + noise; :func:`sensorless.data.imu.base_acceleration` turns it into ``base_a``).
"""

from __future__ import annotations

import inspect
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from ..data.imu import gravity_in_base
from ..data.trajectory import Trajectory
from ..errors import RobotModelError, SensorlessError
from ..robot import Robot, load_robot
from .mujoco_scene import MujocoScene, build_scene, mj_to_pin_state
from .quadruped_plans import SCENARIOS, _Context, _Plan, _rpy_rate_to_omega, _rpy_to_matrix
from .quadruped_profiles import PROFILES, QuadrupedProfile, profile_for, quadruped_robot, spot_mjcf
from .synthetic import TruthModel, perturbed_truth

__all__ = [
    "PROFILES",
    "SCENARIOS",
    "NoiseSpec",
    "QuadrupedProfile",
    "SimulationError",
    "SimulationTruth",
    "benchmark_simulation",
    "dataset",
    "make_truth",
    "quadruped_robot",
    "spot_mjcf",
    "simulate",
    "stance_residual",
]

JOINT_TERMS = ("fv", "fc", "offset", "armature")


class SimulationError(SensorlessError, ValueError):
    """Invalid simulation settings, an infeasible scenario plan, or a fall with ``on_fall="raise"``."""


# ---------------------------------------------------------------------------------------
# settings
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class NoiseSpec:
    """Standard deviations of the white Gaussian noise added to the logged signals."""

    q: float = 1e-4  # rad (encoder)
    v: float = 1e-2  # rad/s
    tau: float = 0.02  # N·m (motor current x torque constant)
    base_position: float = 1e-3  # m
    base_orientation: float = 2e-3  # rad (random rotation vector, base frame)
    base_linear_velocity: float = 1e-2  # m/s
    base_angular_velocity: float = 1e-2  # rad/s
    imu_acc: float = 3e-2  # m/s² (accelerometer at the base origin, base axes)

    @classmethod
    def none(cls) -> NoiseSpec:
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def make_truth(robot: Robot, truth_seed: int = 0, profile: QuadrupedProfile | None = None, **perturb) -> TruthModel:
    """The simulated robot: ``perturbed_truth(robot, rng=truth_seed, mass_scale=, com_shift=)``
    (profile values unless given in ``perturb``) with joint
    friction ``fv ~ U(fv_range)``, ``fc ~ U(fc_range)``, armature ``~ armature·U(0.5, 1.5)``
    from ``profile`` and zero torque offset."""
    prof = profile_for(robot, profile)
    rng = np.random.default_rng(truth_seed)
    perturb = {"mass_scale": prof.mass_scale, "com_shift": prof.com_shift, **perturb}
    truth = perturbed_truth(robot, rng=rng, friction=False, armature=prof.armature, **perturb)
    n = robot.n_actuated
    truth.fv = rng.uniform(*prof.fv_range, n)
    truth.fc = rng.uniform(*prof.fc_range, n)
    truth.offset = np.zeros(n)
    truth.robot.name = robot.name + "_truth"
    return truth


# ---------------------------------------------------------------------------------------
# ground truth
# ---------------------------------------------------------------------------------------
@dataclass
class SimulationTruth:
    """What only the simulation knows, at the logged instants (noiseless).

    Joint arrays are in ``truth.robot.joint_names`` order; base twist/acceleration in the
    base frame (LOCAL); ``contact_forces`` are the floor's forces on each foot in the world
    frame (N, n_feet, 3); ``friction_torque`` is the joint friction MuJoCo applied
    (−fv v − friction loss), so ``M v̇ + h = Sᵀ(tau + friction_torque) + Jcᵀ f`` holds
    with the contact forces applied at the contact points (sphere bottoms).
    ``parameters`` is ``truth.parameters(joint_terms)`` (layout of
    ``ModelStructure(truth.robot, joint_terms=joint_terms)``).
    """

    truth: TruthModel
    parameters: np.ndarray
    joint_terms: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    base_q: np.ndarray
    base_v: np.ndarray
    base_a: np.ndarray
    contact: np.ndarray
    contact_forces: np.ndarray
    contact_points: np.ndarray
    foot_height: np.ndarray
    friction_torque: np.ndarray
    foot_frames: tuple[str, ...]
    foot_radius: float
    noise: NoiseSpec
    scenario: str
    settings: dict[str, Any]
    fell: bool = False
    fall_time: float | None = None
    wall_time: float = 0.0

    @property
    def robot(self) -> Robot:
        return self.truth.robot

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def trajectory(self) -> Trajectory:
        """The noiseless log (q, v, a, tau, base state, contact flags) as a Trajectory."""
        return Trajectory(
            t=self.t,
            q=self.q,
            v=self.v,
            a=self.a,
            tau=self.tau,
            base_q=self.base_q,
            base_v=self.base_v,
            base_a=self.base_a,
            joint_names=self.truth.robot.joint_names,
            extras={"contact": self.contact, "foot_height": self.foot_height, "contact_forces": self.contact_forces},
            source=f"<mujoco truth {self.scenario}>",
        )

    def take(self, index) -> SimulationTruth:
        per_sample = [
            "t",
            "q",
            "v",
            "a",
            "tau",
            "base_q",
            "base_v",
            "base_a",
            "contact",
            "contact_forces",
            "contact_points",
            "foot_height",
            "friction_torque",
        ]
        return replace(self, **{k: getattr(self, k)[index] for k in per_sample})

    def summary(self) -> dict[str, Any]:
        r = self.truth.robot
        return {
            "scenario": self.scenario,
            "samples": len(self),
            "duration": float(self.t[-1] - self.t[0]) if len(self) else 0.0,
            "fell": self.fell,
            "fall_time": self.fall_time,
            "contact_fraction": self.contact.mean(axis=0).tolist() if len(self) else [],
            "total_mass": float(sum(r.model.inertias[j].mass for j in range(1, r.model.njoints))),
            "fv": self.truth.fv.tolist(),
            "fc": self.truth.fc.tolist(),
            "armature": self.truth.armature.tolist(),
            "noise": asdict(self.noise),
            "settings": self.settings,
            "wall_time": self.wall_time,
        }


# ---------------------------------------------------------------------------------------
# inverse kinematics and references
# ---------------------------------------------------------------------------------------
class _LegIK:
    """Damped Newton IK of foot-centre positions in the base frame (base at the identity)."""

    def __init__(self, robot: Robot, feet: Sequence[str]):
        self.model = robot.model
        self.data = self.model.createData()
        self.fids = [robot.frame_id(f) for f in feet]
        self.jq = np.array([robot.q_index(n) for n in robot.joint_names])
        self.jv = np.array([robot.v_index(n) for n in robot.joint_names])
        self.legs = []
        for fid in self.fids:
            joint = self.model.frames[fid].parentJoint
            sup = [j for j in self.model.supports[joint].tolist() if j > 1]
            self.legs.append(np.array([self.model.joints[j].idx_v for j in sup]))
        if len({leg.size for leg in self.legs}) != 1:
            raise RobotModelError("leg IK needs the same number of joints in every leg")
        self.legs_q = np.concatenate(
            [
                [
                    self.model.joints[j].idx_q
                    for j in self.model.supports[self.model.frames[f].parentJoint].tolist()
                    if j > 1
                ]
                for f in self.fids
            ]
        )
        self.q = pin.neutral(self.model)

    def positions(self, qj: np.ndarray) -> np.ndarray:
        q = self.q
        q[self.jq] = qj
        pin.framesForwardKinematics(self.model, self.data, q)
        return np.array([self.data.oMf[f].translation for f in self.fids])

    def solve(
        self, targets: np.ndarray, qj: np.ndarray, tol: float = 1e-7, max_iter: int = 50
    ) -> tuple[np.ndarray, float]:
        m, d, q = self.model, self.data, self.q
        q[self.jq] = qj
        err = np.inf
        eye = 1e-8 * np.eye(3)
        for _ in range(max_iter):
            pin.computeJointJacobians(m, d, q)
            pin.updateFramePlacements(m, d)
            e = targets - np.array([d.oMf[f].translation for f in self.fids])
            err = float(np.abs(e).max())
            if err < tol:
                break
            J = np.array(
                [
                    pin.getFrameJacobian(m, d, f, pin.LOCAL_WORLD_ALIGNED)[:3, leg]
                    for f, leg in zip(self.fids, self.legs)
                ]
            )
            JJt = J @ J.transpose(0, 2, 1) + eye
            dq = np.einsum("fji,fj->fi", J, np.linalg.solve(JJt, e[..., None])[..., 0])
            q[self.legs_q] += np.clip(dq, -0.3, 0.3).ravel()
        return q[self.jq].copy(), err


@dataclass
class _References:
    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    a: np.ndarray
    w: np.ndarray
    dw: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    stance: np.ndarray
    ik_error: float


def _references(ctx: _Context, plan: _Plan, q_stand: np.ndarray, stride: int) -> _References:
    from scipy.interpolate import CubicSpline

    t = ctx.t
    dt = t[1] - t[0]
    R = _rpy_to_matrix(plan.base_rpy)
    v = np.gradient(plan.base_pos, dt, axis=0, edge_order=2)
    a = np.gradient(v, dt, axis=0, edge_order=2)
    drpy = np.gradient(plan.base_rpy, dt, axis=0, edge_order=2)
    w = _rpy_rate_to_omega(plan.base_rpy, drpy)
    dw = np.gradient(w, dt, axis=0, edge_order=2)
    ik = _LegIK(ctx.robot, ctx.profile.feet)
    idx = np.unique(np.r_[np.arange(0, t.size, stride), t.size - 1])
    qs = np.empty((idx.size, q_stand.size))
    qj = q_stand.copy()
    worst, t_worst = 0.0, 0.0
    for n, k in enumerate(idx):
        targets = (plan.feet[k] - plan.base_pos[k]) @ R[k]  # Rᵀ (p_foot − p_base), row-wise
        qj, err = ik.solve(targets, qj)
        if err > worst:
            worst, t_worst = err, t[k] - ctx.t0
        qs[n] = qj
    if worst > 1e-4:
        raise SimulationError(
            f"the scenario plan asks for unreachable foot positions (IK error {worst:.3g} m at t = {t_worst:.2f} s); "
            "reduce its speed, step length or amplitude"
        )
    if stride == 1:
        q = qs
        dq = np.gradient(q, dt, axis=0, edge_order=2)
        ddq = np.gradient(dq, dt, axis=0, edge_order=2)
    else:
        sp = CubicSpline(t[idx], qs, axis=0)
        q, dq, ddq = sp(t), sp(t, 1), sp(t, 2)
    return _References(plan.base_pos, R, v, a, w, dw, q, dq, ddq, plan.stance, worst)


# ---------------------------------------------------------------------------------------
# simulation
# ---------------------------------------------------------------------------------------
def _robot_arg(robot: Robot | str) -> Robot:
    return load_robot(robot) if isinstance(robot, str) else robot


def _stand_configuration(robot: Robot, prof: QuadrupedProfile) -> np.ndarray:
    missing = [j for j in robot.joint_names if j not in prof.stand]
    if missing:
        raise RobotModelError(f"the profile has no standing angle for joint(s) {missing}")
    return np.array([prof.stand[j] for j in robot.joint_names])


def simulate(
    scenario: str,
    robot: Robot | str = "solo12",
    duration: float = 10.0,
    seed: int = 0,
    log_rate: float = 100.0,
    noise: NoiseSpec | None = None,
    truth_seed: int = 0,
    *,
    truth: TruthModel | None = None,
    profile: QuadrupedProfile | None = None,
    sim_rate: float = 1000.0,
    settle: float = 0.5,
    ik_stride: int = 5,
    on_fall: str = "truncate",
    coulomb_velocity: float = 0.0,
    tau_log: str = "sample",
    **scenario_kwargs,
) -> tuple[Trajectory, SimulationTruth]:
    """Simulate ``scenario`` for ``duration`` s and return (user's log, ground truth).

    ``robot`` is the nominal model (the controller's); the simulated robot is ``truth``
    or ``make_truth(robot, truth_seed, profile)``. ``seed`` drives the scenario's random
    choices and the noise (independent streams). The robot first stands for ``settle`` s
    (not logged); logged times start at 0. ``sim_rate`` must be a multiple of ``log_rate``.
    A fall (base below half the standing height or tilted beyond 50°) stops the episode:
    ``on_fall="truncate"`` keeps the samples before it (``truth.fell``, a warning and the
    log's ``source`` say so), ``"raise"`` raises :class:`SimulationError`.
    ``coulomb_velocity`` ε > 0 simulates joint Coulomb friction as fc tanh(v/ε) instead of
    MuJoCo's stiction-like friction loss (:func:`~.mujoco_scene.build_scene`).
    ``tau_log="sample"`` logs the actuator force of the logged step; ``"mean"`` its mean over
    the log period [t_k, t_k + 1/log_rate) (an anti-aliased torque log: ∫τ dt over each
    period is then exact, what the acceleration-free identification integrates); the
    ground truth's ``tau`` is the same quantity without noise.
    Extra keyword arguments go to the scenario planner (see :data:`SCENARIOS`).
    """
    if scenario not in SCENARIOS:
        raise SimulationError(f"unknown scenario {scenario!r}; choose from {sorted(SCENARIOS)}")
    params = list(inspect.signature(SCENARIOS[scenario]).parameters)[2:]
    unknown = sorted(set(scenario_kwargs) - set(params))
    if unknown:
        raise SimulationError(f"scenario {scenario!r} has no setting(s) {unknown}; its settings are {params}")
    if on_fall not in ("truncate", "raise"):
        raise SimulationError(f"on_fall must be 'truncate' or 'raise', got {on_fall!r}")
    if tau_log not in ("sample", "mean"):
        raise SimulationError(f"tau_log must be 'sample' or 'mean', got {tau_log!r}")
    if not (duration > 0 and log_rate > 0 and sim_rate > 0):
        raise SimulationError(f"duration, log_rate and sim_rate must be > 0 (got {duration}, {log_rate}, {sim_rate})")
    ratio = sim_rate / log_rate
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise SimulationError(f"sim_rate ({sim_rate} Hz) must be an integer multiple of log_rate ({log_rate} Hz)")
    decim = round(ratio)
    wall0 = time.perf_counter()
    nominal = _robot_arg(robot)
    prof = profile_for(nominal, profile)
    truth = truth if truth is not None else make_truth(nominal, truth_seed, prof)
    noise = noise if noise is not None else NoiseSpec()
    plan_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))

    dt = 1.0 / sim_rate
    scene = build_scene(
        truth.robot,
        fv=truth.fv,
        fc=truth.fc,
        armature=truth.armature,
        foot_frames=prof.feet,
        foot_radius=prof.foot_radius,
        torque_limit=prof.torque_limit,
        timestep=dt,
        ground_friction=prof.friction_coefficient,
        coulomb_velocity=coulomb_velocity,
    )
    n_log = int(np.floor(duration * log_rate + 1e-9))
    n_settle = round(settle * sim_rate)
    n_steps = n_settle + n_log * decim
    pad = round((1.0 if scenario == "jump" else 0.0) * sim_rate)
    t_grid = np.arange(n_steps + pad + 1) * dt

    q_stand = _stand_configuration(nominal, prof)
    ik = _LegIK(nominal, prof.feet)
    feet_b = ik.positions(q_stand)
    height = prof.foot_radius - float(feet_b[:, 2].mean())
    ctx = _Context(nominal, prof, feet_b, height, t_grid, settle)
    plan = SCENARIOS[scenario](ctx, plan_rng, **scenario_kwargs)
    ref = _references(ctx, plan, q_stand, ik_stride)

    ctrl = _Controller(nominal, scene, prof, ref)
    m, d = scene.model, scene.make_data()
    q0 = nominal.full_configuration(ref.q[0], np.r_[plan.base_pos[0], pin.Quaternion(ref.R[0]).coeffs()])
    scene.set_state(d, q0[0])

    nq, nv, F = m.nq, m.nv, scene.n_feet
    L = {
        "qpos": np.zeros((n_log, nq)),
        "qvel": np.zeros((n_log, nv)),
        "qacc": np.zeros((n_log, nv)),
        "act": np.zeros((n_log, m.nu)),
        "flags": np.zeros((n_log, F), dtype=bool),
        "forces": np.zeros((n_log, F, 3)),
        "points": np.zeros((n_log, F, 3)),
        "height": np.zeros((n_log, F)),
        "fric": np.zeros((n_log, m.nu)),
        "idx": np.zeros(n_log, dtype=int),
    }
    flights = plan.flights
    fall_z = 0.5 * height
    fall_cos = np.cos(np.deg2rad(50.0))
    fell, fall_time, n_done = False, None, 0
    base_id = scene.base_body
    offset, held = 0, 0
    K = t_grid.size
    for k in range(n_steps):
        mujoco.mj_step1(m, d)
        scene.apply_coulomb(d)
        idx = min(max(k - offset, 0), K - 1)
        if flights:
            idx, offset, held = _retime(idx, offset, held, flights, d.ncon, sim_rate)
        d.ctrl[:] = ctrl(idx, d)
        log = k >= n_settle and (k - n_settle) % decim == 0
        if log:
            i = (k - n_settle) // decim
            L["qpos"][i] = d.qpos
            L["qvel"][i] = d.qvel
            L["height"][i] = d.geom_xpos[scene.foot_geoms, 2] - scene.foot_radius
            L["idx"][i] = idx
        mujoco.mj_step2(m, d)
        if tau_log == "mean" and k >= n_settle:  # the force applied during step k
            L["act"][(k - n_settle) // decim] += d.actuator_force / decim
        if log:
            L["qacc"][i] = d.qacc
            if tau_log == "sample":
                L["act"][i] = d.actuator_force
            flags, forces, points = _contacts(scene, d)
            L["flags"][i], L["forces"][i], L["points"][i] = flags, forces, points
            L["fric"][i] = scene.joint_friction(d)
            n_done = i + 1
            R22 = d.xmat[base_id, 8]
            unstable = d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
            if d.qpos[2] < fall_z or R22 < fall_cos or unstable:
                fell, fall_time = True, float(i / log_rate)
                break
    if fell:
        msg = f"{scenario} (seed {seed}): the robot fell at t = {fall_time:.2f} s; the log stops there"
        if on_fall == "raise":
            raise SimulationError(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
        if tau_log == "mean":
            n_done = max(n_done - 1, 0)  # the last period was cut short
    L = {k: v[:n_done] for k, v in L.items()}
    wall = time.perf_counter() - wall0
    traj, gt = _assemble(
        scenario,
        scene,
        truth,
        nominal,
        plan,
        ref,
        L,
        noise,
        noise_rng,
        log_rate,
        decim,
        sim_rate,
        settle,
        seed,
        truth_seed,
        scenario_kwargs,
        fell,
        fall_time,
        wall,
    )
    gt.settings["tau_log"] = tau_log
    return traj, gt


def _retime(idx: int, offset: int, held: int, flights: list[tuple[int, int]], ncon: int, rate: float):
    """Jump plans: move the planned touchdown to the actual one (≥ 2 feet on the floor)."""
    for lo, td in flights:
        if lo + int(0.05 * rate) <= idx < td and ncon >= 2:
            offset += idx - td  # jump ahead to the touchdown
            return td, offset, 0
        if idx == td and ncon == 0 and held < int(0.3 * rate):
            return td - 1, offset + 1, held + 1  # still in the air: hold the flight reference
    return idx, offset, held


def _contacts(scene: MujocoScene, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flags, world forces on each foot and contact points (force-weighted mean)."""
    flags, forces = scene.foot_contacts(d)
    points = np.full((scene.n_feet, 3), np.nan)
    geoms = scene.foot_geoms
    for i in range(d.ncon):
        c = d.contact[i]
        hit = np.flatnonzero((geoms == c.geom[0]) | (geoms == c.geom[1]))
        if hit.size:
            points[hit[0]] = c.pos  # sphere–plane: one contact per foot
    return flags, forces, points


class _Controller:
    """Inverse-dynamics tracking of the plan with stance-force distribution (nominal model)."""

    def __init__(self, robot: Robot, scene: MujocoScene, prof: QuadrupedProfile, ref: _References):
        self.model = robot.model.copy()
        self.data = self.model.createData()
        self.fids = [robot.frame_id(f) for f in prof.feet]
        nq, nv = self.model.nq, self.model.nv
        jq = np.array([robot.q_index(n) for n in robot.joint_names])
        jv = np.array([robot.v_index(n) for n in robot.joint_names])
        contiguous = (
            np.array_equal(jq, np.arange(7, nq))
            and np.array_equal(jv, np.arange(6, nv))
            and np.array_equal(scene.qpos_adr, np.arange(7, nq))
            and np.array_equal(scene.dof_adr, np.arange(6, nv))
        )
        if not contiguous:
            raise RobotModelError("the quadruped controller needs 1-DoF joints below the free flyer, in model order")
        self.act_cols = np.array([robot.joint_names.index(j) for j in robot.actuated_joints])
        self.lo, self.hi = -scene.torque_limit, scene.torque_limit
        self.prof = prof
        self.ref = ref
        self.base = scene.base_body
        self.q = pin.neutral(self.model)
        self.v = np.zeros(nv)
        self.acc = np.zeros(nv)
        self.mu = prof.friction_coefficient * 0.8
        self.reg = 1e-6 * np.eye(6)

    def __call__(self, k: int, d: mujoco.MjData) -> np.ndarray:
        ref, prof = self.ref, self.prof
        q, v, acc = self.q, self.v, self.acc
        qpos, qvel = d.qpos, d.qvel
        q[:3] = qpos[:3]
        q[3:6] = qpos[4:7]
        q[6] = qpos[3]
        q[7:] = qpos[7:]
        R = d.xmat[self.base].reshape(3, 3)  # base orientation (kinematics of mj_step1)
        vw = qvel[:3]
        wl = qvel[3:6]
        vl = vw @ R
        v[:3] = vl
        v[3:6] = wl
        v[6:] = qvel[6:]
        model, data = self.model, self.data
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        M, h = data.M, data.nle
        # base: PD towards the plan in the world frame, mapped to Pinocchio's LOCAL derivative
        e_rot = pin.log3(ref.R[k] @ R.T)
        kp, kd = prof.base_kp, prof.base_kd
        a_w = ref.a[k] + kp * (ref.p[k] - q[:3]) + kd * (ref.v[k] - vw)
        al_w = ref.dw[k] + kp * e_rot + kd * (ref.w[k] - R @ wl)
        wx, wy, wz = wl
        vx, vy, vz = vl
        acc[:3] = a_w @ R - (wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx)
        acc[3:6] = al_w @ R
        acc[6:] = ref.ddq[k]
        stance = ref.stance[k]
        if stance.any():
            tau_full = M @ acc + h
            Jc = np.concatenate(
                [
                    pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
                    for fid, s in zip(self.fids, stance)
                    if s
                ]
            )
            A = Jc[:, :6]
            G = A.T @ A
            G += self.reg * (np.trace(G) + 1e-6)
            f = (A @ np.linalg.solve(G, tau_full[:6])).reshape(-1, 3)
            fz = np.maximum(f[:, 2], 0.0)
            n = np.sqrt(f[:, 0] ** 2 + f[:, 1] ** 2)
            scale = np.minimum(1.0, self.mu * fz / (n + 1e-12))
            f[:, 0] *= scale
            f[:, 1] *= scale
            f[:, 2] = fz
            tau_j = tau_full[6:] - f.ravel() @ Jc[:, 6:]
        else:  # flight: base acceleration that the joint motion implies
            ab = -np.linalg.solve(M[:6, :6], M[:6, 6:] @ acc[6:] + h[:6])
            tau_j = M[6:, :6] @ ab + M[6:, 6:] @ acc[6:] + h[6:]
        tau_j += prof.kp * (ref.q[k] - q[7:]) + prof.kd * (ref.dq[k] - v[6:])
        return np.minimum(np.maximum(tau_j[self.act_cols], self.lo), self.hi)


def _small_rotation_quat(rotvec: np.ndarray) -> np.ndarray:
    """Quaternions [x y z w] of rotation vectors (N, 3)."""
    ang = np.linalg.norm(rotvec, axis=1, keepdims=True)
    half = 0.5 * ang
    s = np.where(ang > 1e-12, np.sin(half) / np.maximum(ang, 1e-300), 0.5)
    return np.concatenate([rotvec * s, np.cos(half)], axis=1)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of [x y z w] quaternions, batched."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )


def _assemble(
    scenario,
    scene,
    truth,
    nominal,
    plan,
    ref,
    L,
    noise,
    rng,
    log_rate,
    decim,
    sim_rate,
    settle,
    seed,
    truth_seed,
    kwargs,
    fell,
    fall_time,
    wall,
) -> tuple[Trajectory, SimulationTruth]:
    r = truth.robot
    N = L["qpos"].shape[0]
    t = np.arange(N) / log_rate
    Q, V, A = mj_to_pin_state(scene, L["qpos"], L["qvel"], L["qacc"]) if N else (np.zeros((0, r.nq)),) * 3
    if N:
        jv = [r.v_index(n) for n in r.joint_names]
        q_true = L["qpos"][:, scene.qpos_adr]
        v_true, a_true = V[:, jv], A[:, jv]
        base_q, base_v, base_a = Q[:, :7], V[:, :6], A[:, :6]
    else:
        q_true = v_true = a_true = np.zeros((0, len(r.joint_names)))
        base_q, base_v, base_a = np.zeros((0, 7)), np.zeros((0, 6)), np.zeros((0, 6))
    cols = [r.joint_names.index(j) for j in r.actuated_joints]
    tau_true = np.zeros((N, len(r.joint_names)))
    tau_true[:, cols] = L["act"]
    fric = np.zeros((N, len(r.joint_names)))
    fric[:, cols] = L["fric"]

    def noisy(x, s):
        return x + rng.normal(size=x.shape) * s if s > 0 else x.copy()

    meas_q = noisy(q_true, noise.q)
    meas_v = noisy(v_true, noise.v)
    meas_tau = noisy(tau_true, noise.tau)
    bq = base_q.copy()
    bq[:, :3] = noisy(base_q[:, :3], noise.base_position)
    if noise.base_orientation > 0 and N:
        dq = _small_rotation_quat(rng.normal(size=(N, 3)) * noise.base_orientation)
        bq[:, 3:] = _quat_mul(base_q[:, 3:], dq)
        bq[:, 3:] /= np.linalg.norm(bq[:, 3:], axis=1, keepdims=True)
    bv = base_v.copy()
    bv[:, :3] = noisy(base_v[:, :3], noise.base_linear_velocity)
    bv[:, 3:] = noisy(base_v[:, 3:], noise.base_angular_velocity)
    # accelerometer: specific force Rᵀ(p̈ − g) = a_lin + ω × v_b − Rᵀg (see sensorless.data.imu)
    specific_force = base_a[:, :3] + np.cross(base_v[:, 3:], base_v[:, :3]) - gravity_in_base(base_q)
    imu_acc = noisy(specific_force, noise.imu_acc)

    jerr = q_true - ref.q[L["idx"]] if N else np.zeros((0, 1))
    perr = base_q[:, :3] - ref.p[L["idx"]] if N else np.zeros((0, 3))
    settings = {
        "scenario": scenario,
        "robot": nominal.name,
        "seed": seed,
        "truth_seed": truth_seed,
        "duration": float(N / log_rate),
        "log_rate": log_rate,
        "sim_rate": sim_rate,
        "settle": settle,
        "torque_limit": float(np.max(scene.torque_limit)),
        "foot_radius": scene.foot_radius,
        "joint_coulomb": f"tanh(v/{scene.coulomb_velocity:g})" if scene.coulomb_velocity > 0 else "mujoco_frictionloss",
        "ik_error": ref.ik_error,
        "tracking_joint_rms": np.sqrt(np.mean(jerr**2, axis=0)).tolist() if N else [],
        "tracking_base_position_rms": np.sqrt(np.mean(perr**2, axis=0)).tolist() if N else [],
        "kwargs": dict(kwargs),
        "plan": plan.settings,
        "a": "not logged (None): estimate it from q or v, e.g. sensorless.data.savgol_derivatives",
    }
    fell_note = f" FELL at t={fall_time:.2f} s" if fell else ""
    source = f"<mujoco {nominal.name} {scenario} seed={seed} truth_seed={truth_seed}{fell_note}>"
    units = {
        "t": "s",
        "q": "rad",
        "v": "rad/s",
        "tau": "N·m (actuator force + noise)",
        "base_q": "m, quaternion xyzw",
        "base_v": "m/s, rad/s (base frame)",
        "foot_height": "m (foot-sphere bottom above the floor)",
        "imu_acc": "m/s² (specific force at the base origin, base frame; +9.81 z at rest)",
    }
    traj = Trajectory(
        t=t,
        q=meas_q,
        v=meas_v,
        a=None,
        tau=meas_tau,
        base_q=bq,
        base_v=bv,
        base_a=None,
        joint_names=r.joint_names,
        extras={"contact": L["flags"].copy(), "foot_height": L["height"].copy(), "imu_acc": imu_acc},
        units=units,
        source=source,
    )
    gt = SimulationTruth(
        truth=truth,
        parameters=truth.parameters(JOINT_TERMS),
        joint_terms=JOINT_TERMS,
        t=t,
        q=q_true,
        v=v_true,
        a=a_true,
        tau=tau_true,
        base_q=base_q,
        base_v=base_v,
        base_a=base_a,
        contact=L["flags"],
        contact_forces=L["forces"],
        contact_points=L["points"],
        foot_height=L["height"],
        friction_torque=fric,
        foot_frames=scene.foot_frames,
        foot_radius=scene.foot_radius,
        noise=noise,
        scenario=scenario,
        settings=settings,
        fell=fell,
        fall_time=fall_time,
        wall_time=wall,
    )
    return traj, gt


def dataset(
    scenarios: Sequence[tuple[str, dict[str, Any]]],
    seed: int = 0,
    *,
    robot: Robot | str = "solo12",
    truth_seed: int = 0,
    duration: float = 10.0,
    **common,
) -> list[tuple[Trajectory, SimulationTruth]]:
    """Simulate several ``(scenario, kwargs)`` with one truth model and seeds ``seed, seed+1, …``.

    ``kwargs`` may override ``duration``/``log_rate``/``noise``; ``common`` applies to all.
    """
    robot = _robot_arg(robot)
    truth = make_truth(robot, truth_seed, common.get("profile"))
    out = []
    for k, (name, kw) in enumerate(scenarios):
        kw = {"duration": duration, **common, **kw}
        out.append(simulate(name, robot, seed=seed + k, truth_seed=truth_seed, truth=truth, **kw))
    return out


# ---------------------------------------------------------------------------------------
# rigid-contact consistency of the simulated data
# ---------------------------------------------------------------------------------------
def stance_residual(
    truth: SimulationTruth,
    robot: Robot | None = None,
    *,
    friction: str = "actual",
    contact_point: str = "frame",
    mask: np.ndarray | None = None,
) -> dict[str, Any]:
    """Projected residual r = P (M v̇ + h − Sᵀ τ − Sᵀ τ_f) on the noiseless logged states.

    P = I − Jc⁺Jc with Jc the stacked 3-D Jacobians (LOCAL_WORLD_ALIGNED) of the feet in
    contact (``truth.contact``). ``robot`` (default: the true robot, with its armature)
    supplies M and h. ``friction="actual"`` uses MuJoCo's applied joint friction
    (``truth.friction_torque``), ``"model"`` the law −fv v − fc sgn v, ``"none"`` nothing.
    ``contact_point="frame"`` takes the Jacobian at the foot frame (the sphere centre, as an
    identification would), ``"contact"`` at MuJoCo's contact point (frame − radius·e_z):
    the difference is the moment arm of the tangential forces. Only samples with at
    least one foot in contact (or ``mask``) are used.

    Returns per-sample ``residual`` and ``reference`` = ‖Sᵀτ‖ norms, and their
    RMS/median/max over the samples, with ``relative = rms(residual) / rms(reference)``.
    """
    if friction not in ("actual", "model", "none"):
        raise SimulationError(f"friction must be 'actual', 'model' or 'none', got {friction!r}")
    if contact_point not in ("frame", "contact"):
        raise SimulationError(f"contact_point must be 'frame' or 'contact', got {contact_point!r}")
    tm = truth.truth
    r = robot if robot is not None else tm.robot
    model = r.model.copy()
    if robot is None:
        model.armature[r.actuated_v_indices] = tm.armature
    data = model.createData()
    sel = truth.contact.any(axis=1) if mask is None else np.asarray(mask, dtype=bool)
    idx = np.flatnonzero(sel)
    Q = r.full_configuration(truth.q[idx], truth.base_q[idx])
    V = r.full_velocity(truth.v[idx], truth.base_v[idx])
    A = r.full_velocity(truth.a[idx], truth.base_a[idx])
    jv = np.array([r.v_index(n) for n in r.joint_names])
    tau = np.zeros((idx.size, r.nv))
    tau[:, jv] = truth.tau[idx]
    if friction == "actual":
        tau[:, jv] += truth.friction_torque[idx]
    elif friction == "model":
        cols = np.array([r.joint_names.index(j) for j in r.actuated_joints])
        vj = truth.v[idx][:, cols]
        tau[:, r.actuated_v_indices] -= tm.fv * vj + tm.fc * np.sign(vj)
    fids = [r.frame_id(f) for f in truth.foot_frames]
    F = len(fids)
    lhs = np.empty((idx.size, r.nv))
    Jc = np.zeros((idx.size, 3 * F, r.nv))
    flags = truth.contact[idx]
    for n in range(idx.size):
        lhs[n] = pin.rnea(model, data, Q[n], V[n], A[n])
        pin.computeJointJacobians(model, data, Q[n])
        pin.updateFramePlacements(model, data)
        for i, fid in enumerate(fids):
            if flags[n, i]:
                J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
                if contact_point == "contact":
                    # point p_c = p_f − ρ e_z: v_c = v_f + ω × (−ρ e_z) = v_f + ρ [e_z]× ω
                    ez = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
                    Jc[n, 3 * i : 3 * i + 3] = J[:3] + truth.foot_radius * ez @ J[3:]
                else:
                    Jc[n, 3 * i : 3 * i + 3] = J[:3]
    from ..regressor.contact import null_space_projector

    P = null_space_projector(Jc)
    res = np.einsum("nij,nj->ni", P, lhs - tau)
    rn = np.linalg.norm(res, axis=1)
    ref = np.linalg.norm(truth.tau[idx], axis=1)  # ‖Sᵀτ‖

    def rms(x):
        return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")

    return {
        "samples": int(idx.size),
        "residual": rn,
        "reference": ref,
        "residual_rms": rms(rn),
        "residual_median": float(np.median(rn)) if rn.size else float("nan"),
        "residual_max": float(rn.max()) if rn.size else float("nan"),
        "reference_rms": rms(ref),
        "relative": rms(rn) / rms(ref) if rn.size else float("nan"),
        "friction": friction,
        "contact_point": contact_point,
    }


def benchmark_simulation(
    duration: float = 10.0, scenarios: Sequence[str] = ("wobble", "trot", "crawl", "jump"), seed: int = 0
) -> dict[str, Any]:
    """Wall time per simulated second for each scenario (Solo12, defaults). JSON-able."""
    out: dict[str, Any] = {"duration": duration, "scenarios": {}}
    robot = load_robot("solo12")
    for name in scenarios:
        t0 = time.perf_counter()
        _, gt = simulate(name, robot, duration=duration, seed=seed)
        wall = time.perf_counter() - t0
        out["scenarios"][name] = {
            "wall_s": wall,
            "wall_per_sim_s": wall / max(gt.settings["duration"], 1e-9),
            "fell": gt.fell,
            "samples": len(gt),
        }
    return out

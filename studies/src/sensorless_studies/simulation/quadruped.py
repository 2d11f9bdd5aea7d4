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

from dataclasses import fields
import time
import warnings
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.errors import RobotModelError, SimulationError
from sensorless.robot import Robot, load_robot
from .mujoco_scene import MujocoScene, build_scene
from .quadruped_control import Controller, LegIK, references
from .quadruped_log import Episode, SimulationTruth, assemble
from .quadruped_plans import SCENARIOS, PlanContext
from .quadruped_profiles import QuadrupedProfile, profile_for
from sensorless.testing import NoiseSpec, TruthModel, perturbed_truth

#: what the torque log holds: the actuator force of the logged step, or its mean over the log period
TAU_LOGS = ("sample", "mean")

__all__ = [
    "TAU_LOGS",
    "dataset",
    "make_truth",
    "simulate",
    "stance_residual",
]


def make_truth(robot: Robot, truth_seed: int = 0, profile: QuadrupedProfile | None = None, **perturb) -> TruthModel:
    """The simulated robot: ``perturbed_truth(robot, rng=truth_seed, mass_scale=, com_shift=)``
    (profile values unless given in ``perturb``) with joint
    friction ``fv ~ U(fv_range)``, ``fc ~ U(fc_range)``, armature ``~ armature·U(0.5, 1.5)``
    from ``profile`` and zero torque offset."""
    prof = profile_for(robot, profile)
    rng = np.random.default_rng(truth_seed)
    ranges = prof.truth
    perturb = {"mass_scale": ranges.mass_scale, "com_shift": ranges.com_shift, **perturb}
    truth = perturbed_truth(robot, rng=rng, friction=False, armature=ranges.armature, **perturb)
    n = robot.n_actuated
    truth.fv = rng.uniform(*ranges.fv_range, n)
    truth.fc = rng.uniform(*ranges.fc_range, n)
    truth.offset = np.zeros(n)
    truth.robot.name = robot.name + "_truth"
    return truth


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
    params = [f.name for f in fields(SCENARIOS[scenario])]
    unknown = sorted(set(scenario_kwargs) - set(params))
    if unknown:
        raise SimulationError(f"scenario {scenario!r} has no setting(s) {unknown}; its settings are {params}")
    if on_fall not in ("truncate", "raise"):
        raise SimulationError(f"on_fall must be 'truncate' or 'raise', got {on_fall!r}")
    if tau_log not in TAU_LOGS:
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
        torque_limit=prof.gains.torque_limit,
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
    ik = LegIK(nominal, prof.feet)
    feet_b = ik.positions(q_stand)
    height = prof.foot_radius - float(feet_b[:, 2].mean())
    ctx = PlanContext(nominal, prof, feet_b, height, t_grid, settle)
    plan = SCENARIOS[scenario](**scenario_kwargs).plan(ctx, plan_rng)
    ref = references(ctx, plan, q_stand, ik_stride)

    ctrl = Controller(nominal, scene, prof, ref)
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
    episode = Episode(
        scenario=scenario, scene=scene, truth=truth, nominal=nominal, plan=plan, ref=ref, log=L, log_rate=log_rate,
        sim_rate=sim_rate, settle=settle, seed=seed, truth_seed=truth_seed, kwargs=scenario_kwargs, fell=fell,
        fall_time=fall_time, wall_time=wall,
    )
    traj, gt = assemble(episode, noise, noise_rng)
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
    from sensorless.regressor.contact_kinematics import null_space_projector

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

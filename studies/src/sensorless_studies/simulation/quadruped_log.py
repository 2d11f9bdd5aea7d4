"""The simulated quadruped's log and ground truth: noise model, :class:`SimulationTruth`, and
:func:`assemble` that turns one recorded episode into (user's log, ground truth).

Logged signals: joint encoders ``q``, ``v`` and the actuator force ``tau`` (+ white noise),
the base pose (position + noise, orientation ⊗ exp(noise rotation vector)) and LOCAL twist
(+ noise), contact flags, foot heights, and the accelerometer at the base origin,
specific force Rᵀ(p̈ − g) = a_lin + ω × v_b − Rᵀg (base axes, + noise).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sensorless.data.imu import gravity_in_base
from sensorless.data.trajectory import Trajectory
from sensorless.robot import Robot
from .mujoco_scene import MujocoScene, mj_to_pin_state
from .quadruped_control import References
from .quadruped_plans import Plan
from sensorless.testing import NoiseSpec, TruthModel, add_white_noise

#: the joint terms the simulated quadruped has (and its logs' truth parameters are laid out in)
JOINT_TERMS = ("fv", "fc", "offset", "armature")
#: the rigid-body state arrays a :class:`SimulationTruth` shares, by name, with a :class:`Trajectory`
_STATE = ("t", "q", "v", "a", "tau", "base_q", "base_v", "base_a")
#: its other per-sample arrays (what :meth:`SimulationTruth.take` slices besides the state)
_CONTACT = ("contact", "contact_forces", "contact_points", "foot_height", "friction_torque")

__all__ = ["Episode", "RunOutcome", "SimulationTruth", "assemble", "noisy_orientation"]


@dataclass(kw_only=True)
class RunOutcome:
    """How a simulated run ended: whether (and when, in s of log time) the robot fell, and the
    wall-clock seconds it took. Shared by :class:`Episode` and the :class:`SimulationTruth` it yields."""

    fell: bool = False
    fall_time: float | None = None
    wall_time: float = 0.0


@dataclass
class SimulationTruth(RunOutcome):
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

    @property
    def robot(self) -> Robot:
        return self.truth.robot

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def trajectory(self) -> Trajectory:
        """The noiseless log (q, v, a, tau, base state, contact flags) as a Trajectory."""
        return Trajectory(
            **{k: getattr(self, k) for k in _STATE},
            joint_names=self.truth.robot.joint_names,
            extras={"contact": self.contact, "foot_height": self.foot_height, "contact_forces": self.contact_forces},
            source=f"<mujoco truth {self.scenario}>",
        )

    def take(self, index) -> SimulationTruth:
        return replace(self, **{k: getattr(self, k)[index] for k in _STATE + _CONTACT})

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


@dataclass
class Episode(RunOutcome):
    """One simulated run as recorded: the settings, the scene, the true and nominal robots, the
    plan and references, and ``log`` (per logged sample: ``qpos``, ``qvel``, ``qacc``, ``act``,
    ``fric``, ``flags``, ``forces``, ``points``, ``height``, ``idx`` = reference index)."""

    scenario: str
    scene: MujocoScene
    truth: TruthModel
    nominal: Robot
    plan: Plan
    ref: References
    log: dict[str, np.ndarray]
    log_rate: float
    sim_rate: float
    settle: float
    seed: int
    truth_seed: int
    kwargs: dict[str, Any]


def noisy_orientation(quat_xyzw: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """q ⊗ exp(δθ), δθ ~ N(0, σ² I) a rotation vector in the base frame; unit quaternions [x y z w]."""
    noisy = (Rotation.from_quat(quat_xyzw) * Rotation.from_rotvec(rng.normal(size=(len(quat_xyzw), 3)) * sigma)).as_quat()
    return noisy / np.linalg.norm(noisy, axis=1, keepdims=True)


def assemble(ep: Episode, noise: NoiseSpec, rng: np.random.Generator) -> tuple[Trajectory, SimulationTruth]:
    """(user's log with ``noise`` drawn from ``rng``, noiseless ground truth) of episode ``ep``."""
    scenario, scene, truth, nominal, plan, ref, L = ep.scenario, ep.scene, ep.truth, ep.nominal, ep.plan, ep.ref, ep.log
    log_rate, seed, truth_seed, fell, fall_time = ep.log_rate, ep.seed, ep.truth_seed, ep.fell, ep.fall_time
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
    true = dict(zip(_STATE, (t, q_true, v_true, a_true, tau_true, base_q, base_v, base_a)))
    meas = {k: add_white_noise(true[k], getattr(noise, k), rng) for k in ("q", "v", "tau")}  # drawn in this order
    bq = base_q.copy()
    bq[:, :3] = add_white_noise(base_q[:, :3], noise.base_position, rng)
    if noise.base_orientation > 0 and N:
        bq[:, 3:] = noisy_orientation(base_q[:, 3:], noise.base_orientation, rng)
    bv = base_v.copy()
    bv[:, :3] = add_white_noise(base_v[:, :3], noise.base_linear_velocity, rng)
    bv[:, 3:] = add_white_noise(base_v[:, 3:], noise.base_angular_velocity, rng)
    # accelerometer: specific force Rᵀ(p̈ − g) = a_lin + ω × v_b − Rᵀg (see sensorless.data.imu)
    specific_force = base_a[:, :3] + np.cross(base_v[:, 3:], base_v[:, :3]) - gravity_in_base(base_q)
    imu_acc = add_white_noise(specific_force, noise.imu_acc, rng)

    jerr = q_true - ref.q[L["idx"]] if N else np.zeros((0, 1))
    perr = base_q[:, :3] - ref.p[L["idx"]] if N else np.zeros((0, 3))
    settings = {
        "scenario": scenario,
        "robot": nominal.name,
        "seed": seed,
        "truth_seed": truth_seed,
        "duration": float(N / log_rate),
        "log_rate": log_rate,
        "sim_rate": ep.sim_rate,
        "settle": ep.settle,
        "torque_limit": float(np.max(scene.torque_limit)),
        "foot_radius": scene.foot_radius,
        "joint_coulomb": f"tanh(v/{scene.coulomb_velocity:g})" if scene.coulomb_velocity > 0 else "mujoco_frictionloss",
        "ik_error": ref.ik_error,
        "tracking_joint_rms": np.sqrt(np.mean(jerr**2, axis=0)).tolist() if N else [],
        "tracking_base_position_rms": np.sqrt(np.mean(perr**2, axis=0)).tolist() if N else [],
        "kwargs": dict(ep.kwargs),
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
        **meas,
        a=None,
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
        **true,
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
        **{f.name: getattr(ep, f.name) for f in fields(RunOutcome)},
    )
    return traj, gt

"""A 2-DoF hopping leg on a vertical rail, simulated in MuJoCo, with a force plate under the foot.

The robot is a *fixed-base* model whose unactuated "base" is a joint: a carriage slides on a
vertical rail (prismatic joint ``rail``, passive: no motor, no torque channel) and carries the
hip (``hip``, revolute about y) and the knee (``knee``); the foot (frame ``foot``, a sphere of
radius :data:`FOOT_RADIUS`) hops on the ground. Joint torques are logged on the hip and the knee
only; the force plate gives the ground-truth contact force.

:func:`leg_urdf` writes the URDF of a set of body parameters (:class:`LegBodies`): the user's CAD
file (:data:`CAD`) and a "true" robot whose masses and inertias differ from it by 15–30 % on
every body (:data:`TRUTH`). :func:`simulate_hops` runs the true robot in a MuJoCo scene built
from it (:func:`~.mujoco_scene.build_scene`, rail friction included) under a hopping controller
(joint PD targets switched by the contact phase: flight with hip swing, compression, thrust, and
now and then a slow squat while standing) and returns a :class:`HopLog`; :func:`write_hop_log`
writes it as an NPZ: ``t``, ``q``, ``v`` (3 joints), ``tau`` (hip and knee only), ``joint_names``,
``contact`` flags and ``contact_forces`` (the force of the plate on the foot, world axes).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

__all__ = ["CAD", "FOOT", "FOOT_RADIUS", "HopLog", "LegBodies", "TRUTH", "leg_robot", "leg_urdf", "simulate_hops",
           "write_hop_log"]

FOOT = "foot"
FOOT_RADIUS = 0.02
RAIL, HIP, KNEE = "rail", "hip", "knee"
LINK = 0.2  # thigh and shank length [m]
ACTUATOR_LAG = 0.01  # time constant [s] of the drives' torque response to a command
SOLREF = 0.02  # contact time constant [s] (a rubber foot pad on the plate)


@dataclass(frozen=True)
class LegBodies:
    """Mass [kg], CoM [m] (own frame) and diagonal inertia about the CoM [kg m²] of carriage, thigh, shank."""

    mass: tuple[float, float, float] = (1.5, 0.6, 0.3)
    com: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.03), (0.0, 0.0, -0.08), (0.0, 0.0, -0.09))
    inertia: tuple[tuple[float, float, float], ...] = ((4e-3, 4e-3, 3e-3), (2.4e-3, 2.4e-3, 3e-4),
                                                        (1.2e-3, 1.2e-3, 1e-4))

    @property
    def total_mass(self) -> float:
        return float(sum(self.mass))


#: the user's CAD description (the prior)
CAD = LegBodies()
#: the robot as built: every body 15–30 % off the CAD (total +15 %)
TRUTH = LegBodies(mass=(1.9, 0.5, 0.36), com=((0.01, 0.0, 0.04), (0.005, 0.0, -0.095), (0.0, 0.0, -0.11)),
                  inertia=((5e-3, 5.2e-3, 3.5e-3), (2.0e-3, 2.1e-3, 2.4e-4), (1.5e-3, 1.5e-3, 1.3e-4)))


def leg_urdf(bodies: LegBodies, path: str | Path, name: str = "rail_leg") -> Path:
    """Write the URDF of the rail-mounted leg with ``bodies`` to ``path`` and return it."""
    links = []
    for link, m, c, inertia in zip(("carriage", "thigh", "shank"), bodies.mass, bodies.com, bodies.inertia):
        links.append(f'''  <link name="{link}">
    <inertial><origin xyz="{c[0]} {c[1]} {c[2]}" rpy="0 0 0"/><mass value="{m}"/>
      <inertia ixx="{inertia[0]}" ixy="0" ixz="0" iyy="{inertia[1]}" iyz="0" izz="{inertia[2]}"/></inertial>
  </link>''')
    text = f'''<?xml version="1.0"?>
<robot name="{name}">
  <link name="world"/>
{links[0]}
{links[1]}
{links[2]}
  <link name="{FOOT}"/>
  <joint name="{RAIL}" type="prismatic"><parent link="world"/><child link="carriage"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="0" upper="2" effort="0" velocity="10"/></joint>
  <joint name="{HIP}" type="revolute"><parent link="carriage"/><child link="thigh"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="20" velocity="30"/></joint>
  <joint name="{KNEE}" type="revolute"><parent link="thigh"/><child link="shank"/>
    <origin xyz="0 0 {-LINK}" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="20" velocity="30"/></joint>
  <joint name="foot_fixed" type="fixed"><parent link="shank"/><child link="{FOOT}"/>
    <origin xyz="0 0 {-LINK}" rpy="0 0 0"/></joint>
</robot>
'''
    path = Path(path)
    path.write_text(text)
    return path


def leg_robot(urdf: str | Path):
    """The leg loaded with its rail passive (:func:`~sensorless.robot.load_robot`)."""
    from sensorless.robot import load_robot

    return load_robot(urdf, passive_joints=(RAIL,))


@dataclass
class HopLog:
    """One simulated log (1 kHz): joint arrays in ``joint_names`` order (rail, hip, knee)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray  # (N, 2): hip, knee (the rail has no motor)
    contact: np.ndarray  # (N,) bool
    force: np.ndarray  # (N, 3) force of the plate on the foot, world axes
    joint_names: tuple[str, ...] = (RAIL, HIP, KNEE)
    settings: dict = field(default_factory=dict)

    @property
    def plate_force(self) -> np.ndarray:
        """What the force plate reads: the force of the foot on the plate (N, 3) = −force."""
        return -self.force


@dataclass(frozen=True)
class Friction:
    """Joint friction of the true robot, per joint (hip, knee, rail): viscous and Coulomb (tanh(v/ε))."""

    fv: tuple[float, float, float] = (0.03, 0.02, 1.5)
    fc: tuple[float, float, float] = (0.06, 0.05, 1.0)
    armature: tuple[float, float] = (4e-3, 4e-3)  # reflected rotor inertia of the hip and knee motors
    epsilon: float = 0.05


def simulate_hops(bodies: LegBodies = TRUTH, *, seed: int = 0, duration: float = 6.0, rate: float = 1000.0,
                  friction: Friction = Friction(), torque_noise: float = 0.03, q_noise: float = 2e-5,
                  v_noise: float = 0.01) -> HopLog:
    """Simulate the leg with ``bodies`` hopping for ``duration`` s (module docstring). The hop pattern
    (touchdown posture, thrust gain, hip swing, when to squat instead of hopping) is drawn from
    ``seed``; sensor noise (white, std ``torque_noise`` N·m, ``q_noise``, ``v_noise``) from it too."""
    import tempfile

    from .mujoco_scene import build_scene

    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as tmp:
        robot = leg_robot(leg_urdf(bodies, Path(tmp) / "truth.urdf"))
    dt = 1.0 / rate
    scene = build_scene(robot, fv=np.array(friction.fv), fc=np.array(friction.fc), armature=np.array(friction.armature),
                        foot_frames=(FOOT,), foot_radius=FOOT_RADIUS, torque_limit=20.0, timestep=dt,
                        contact_solref=(SOLREF, 1.0), coulomb_velocity=friction.epsilon)
    m, d = scene.model, scene.make_data()
    rail, hip, knee = (int(a) for a in scene.qpos_adr)  # joint_names: rail, hip, knee
    dv = scene.dof_adr
    knee0 = 1.0
    d.qpos[rail], d.qpos[hip], d.qpos[knee] = 2 * LINK * np.cos(knee0 / 2) + FOOT_RADIUS + 0.06, -knee0 / 2, knee0
    mujoco.mj_forward(m, d)
    n = int(round(duration * rate))
    out = {k: np.zeros((n, 3)) for k in ("q", "v", "force")}
    out["tau"], out["contact"] = np.zeros((n, 2)), np.zeros(n, dtype=bool)
    ctrl = _HopController(rng)
    for i in range(n):
        mujoco.mj_step1(m, d)
        scene.apply_coulomb(d)
        flags, forces = scene.foot_contacts(d)
        q = np.array([d.qpos[rail], d.qpos[hip], d.qpos[knee]])
        v = np.array([d.qvel[dv[0]], d.qvel[dv[1]], d.qvel[dv[2]]])
        cmd = ctrl(i * dt, q, v, bool(flags[0]))
        d.ctrl[:] = d.ctrl + (dt / (dt + ACTUATOR_LAG)) * (cmd - d.ctrl)  # the drive's current loop: a first-order lag
        out["q"][i], out["v"][i] = q, v
        mujoco.mj_step2(m, d)
        out["tau"][i] = d.actuator_force
        flags, forces = scene.foot_contacts(d)
        out["contact"][i], out["force"][i] = flags[0], forces[0]
    noise = [q_noise * np.array([0.5, 1.0, 1.0]), v_noise, torque_noise]
    q = out["q"] + rng.normal(0.0, 1.0, out["q"].shape) * noise[0]
    v = out["v"] + rng.normal(0.0, noise[1], out["v"].shape)
    tau = out["tau"] + rng.normal(0.0, noise[2], out["tau"].shape)
    settings = {"seed": seed, "duration": duration, "rate": rate, "bodies": _asdict(bodies),
                "friction": _asdict(friction), "noise": {"q": q_noise, "v": v_noise, "tau": torque_noise},
                "hops": ctrl.hops, "squats": ctrl.squats}
    return HopLog(np.arange(n) * dt, q, v, tau, out["contact"], out["force"], settings=settings)


def write_hop_log(log: HopLog, path: str | Path) -> Path:
    """The log as an NPZ a user would have (module docstring); the ground truth is ``contact_forces``."""
    from sensorless.io import write_npz_atomic

    return write_npz_atomic(Path(path), t=log.t, q=log.q, v=log.v, tau=log.tau,
                            joint_names=np.array(log.joint_names), contact=log.contact[:, None].astype(float),
                            contact_forces=log.force[:, None, :])


class _HopController:
    """Joint PD targets by phase: flight (touchdown posture, hip swing), compression (until the
    carriage stops), thrust (knee extension until lift-off); now and then a 0.6 s squat in stance."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.phase, self.since = "flight", 0.0
        self.hops = self.squats = 0
        self._new_hop()
        self.swing = (rng.uniform(0.1, 0.25), rng.uniform(2.0, 4.0), rng.uniform(0, 2 * np.pi))

    def _new_hop(self) -> None:
        r = self.rng
        self.touchdown = r.uniform(0.8, 1.2)
        self.extend = r.uniform(0.25, 0.45)
        self.thrust = r.uniform(25.0, 45.0)
        self.squat = r.uniform() < 0.25

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, contact: bool) -> np.ndarray:
        _, qh, qk = q
        if self.phase == "flight" and contact and t - self.since > 0.05:
            self.phase, self.since = ("squat" if self.squat else "compress"), t
        elif self.phase == "compress" and v[0] >= 0.0:
            self.phase, self.since = "thrust", t
        elif self.phase == "squat" and t - self.since > 0.6:
            self.phase, self.since = "thrust", t
            self.squats += 1
        elif self.phase == "thrust" and (not contact or qk < self.extend + 0.02) and t - self.since > 0.03:
            self.phase, self.since = "flight", t
            self.hops += 1
            self._new_hop()
        a, f, ph = self.swing
        if self.phase == "flight":
            knee_t, kk = self.touchdown, 12.0
            hip_t = -knee_t / 2 + a * np.sin(2 * np.pi * f * t + ph)
        elif self.phase == "compress":
            knee_t, kk, hip_t = self.touchdown, 10.0, -qk / 2
        elif self.phase == "squat":
            knee_t = self.touchdown + 0.25 * np.sin(2 * np.pi * 1.5 * (t - self.since))
            kk, hip_t = 30.0, -qk / 2
        else:
            knee_t, kk, hip_t = self.extend, self.thrust, -qk / 2
        tau_h = 15.0 * (hip_t - qh) - 0.4 * v[1]
        tau_k = kk * (knee_t - qk) - 0.4 * v[2]
        return np.clip([tau_h, tau_k], -20.0, 20.0)


def _asdict(x) -> dict:
    import dataclasses

    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(x).items()}

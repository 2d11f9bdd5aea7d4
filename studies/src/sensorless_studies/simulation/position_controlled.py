"""A simulated position-controlled humanoid leg: TALOS right leg in MuJoCo.

Physics: MuJoCo (scene built with ``mujoco.MjSpec`` from the example-robot-data URDF,
:mod:`.leg_model`), semi-implicit Euler at ``control_dt / substeps`` (default 0.5 ms).
Two set-ups: ``"air"`` (pelvis fixed, leg hanging) and ``"contact"`` (pelvis fixed, sole
plate on a stiff floor placed under the foot at ``Q_CONTACT``).

Actuator (per joint, rigid transmission — motor encoder = joint angle, no elasticity):

    e      = q_cmd − q                                 (closed drive: PD on the motor angle)
    τ_m    = sat( k dz_δ(e) − k_d q̇ + c f_c tanh(q̇ / v_c) )   dead zone δ, velocity-sign term c
    i      = τ_m / (N K_t)                              motor current (measured)
    I_a q̈ = τ_m − b q̇ − τ_f − τ                      rotor (armature I_a), gearbox friction
    |τ_f| ≤ f_c + μ |τ_m|  (stiction, MuJoCo frictionloss), τ_f = ±(f_c + μ|τ_m|) when sliding

τ is the link-side joint torque. The load-dependent Coulomb term μ|τ_m| (gear efficiency)
makes the actuator asymmetric: at steady speed Δq = q_cmd − q satisfies

    Δq ≈ τ / (k (1 − μ)) + (k_d + b)/k q̇ + (1 − c) f_c / k sgn(q̇)    motor drives the load (τ q̇ > 0)
    Δq ≈ τ / (k (1 + μ)) + (k_d + b)/k q̇ + (1 − c) f_c / k sgn(q̇)    load back-drives the motor

and at rest any Δq inside the stiction band is possible. So Kτ = 1/k·(1 ± μ)⁻¹: a single
linear model over-estimates |Δq| on part of the data, whichever Kτ it picks
(:meth:`ActuatorParams.true_model`).

Sensors (noise added in Python, seeded): joint encoders, motor currents, a 6-axis F/T
sensor between ankle and sole plate (MuJoCo force/torque sensor, negated to the
convention of :class:`~sensorless.estimation.joint_torque.FTSensor`), gyro and
accelerometer on the pelvis. Ground truth per tick: link-side torques, contact wrench.
Readings are those of the last physics sub-step of a tick (0.5 ms sensor latency).

Protocols (:mod:`.leg_protocols`): :func:`~.leg_protocols.increasing_sinusoids` (q_d = q_mid + (a0 + a t) sin 2π f t) and
:func:`~.leg_protocols.quasi_static_protocol` (slow high-torque motions with external foot forces in the
air, or pushing into the floor in contact).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.errors import DataError, ShapeMismatchError
from sensorless.estimation.joint_torque import FTSensor, ImuSpec, JointTorqueEstimator
from .leg_model import (
    FT_FRAME,
    IMU_FRAME,
    JOINTS,
    SOLE_FRAME,
    plate_inertia,
    right_leg_mjspec,
    talos_right_leg,
)
from .leg_protocols import Q_AIR, Q_CONTACT

__all__ = [
    "ActuatorParams",
    "PositionControlledLeg",
    "Reading",
    "SensorNoise",
    "SimLog",
    "leg_estimator",
    "simulate",
]



@dataclass
class ActuatorParams:
    """Per-joint drive + gearbox parameters (TALOS-like orders of magnitude)."""

    stiffness: np.ndarray = field(default_factory=lambda: np.array([3000.0, 5000.0, 5000.0, 6000.0, 4000.0, 3000.0]))
    damping: np.ndarray = field(default_factory=lambda: np.array([12.0, 25.0, 35.0, 35.0, 20.0, 12.0]))
    viscous: np.ndarray = field(default_factory=lambda: np.array([1.5, 2.5, 3.0, 3.0, 2.0, 1.5]))
    coulomb: np.ndarray = field(default_factory=lambda: np.array([2.0, 3.0, 3.5, 4.0, 3.0, 2.0]))
    load_friction: float = 0.15  # μ: Coulomb friction grows by μ |τ_m| (gear efficiency ≈ 1 − μ)
    dead_zone: float = 1e-4  # [rad]
    friction_compensation: float = 0.3  # c: the drive adds c f_c tanh(q̇ / v_c)
    compensation_velocity: float = 0.02  # v_c [rad/s]
    torque_limit: np.ndarray = field(default_factory=lambda: np.array([100.0, 160.0, 160.0, 300.0, 160.0, 100.0]))
    rotor_inertia: np.ndarray = field(default_factory=lambda: np.full(6, 0.1))  # reflected, [kg m²]
    gear_ratio: float = 100.0
    torque_constant: float = 0.1  # [Nm/A] motor side

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping", "viscous", "coulomb", "torque_limit", "rotor_inertia"):
            val = np.broadcast_to(np.asarray(getattr(self, name), float), (6,)).copy()
            if np.any(val < 0) or not np.all(np.isfinite(val)):
                raise DataError(f"actuator parameter '{name}' must be finite and ≥ 0, got {val}")
            setattr(self, name, val)
        if not 0 <= self.load_friction < 1:
            raise DataError(f"load_friction μ must be in [0, 1), got {self.load_friction}")

    def true_model(self) -> dict:
        """Analytic Δq-model parameters of the simulated actuator (the fits' ground truth)."""
        k, mu = self.stiffness, self.load_friction
        return {
            "k_tau_static": (1 / k).tolist(),
            "k_tau_drive": (1 / (k * (1 - mu))).tolist(),
            "k_tau_backdrive": (1 / (k * (1 + mu))).tolist(),
            "k_v": ((self.damping + self.viscous) / k).tolist(),
            "k_c": ((1 - self.friction_compensation) * self.coulomb / k).tolist(),
            "k1_current": self.gear_ratio * self.torque_constant,
        }

    def to_dict(self) -> dict:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}


@dataclass
class SensorNoise:
    """Standard deviations of white sensor noise."""

    encoder: float = 2e-5  # rad (≈ 19-bit encoder)
    current: float = 0.02  # A
    ft_force: float = 0.3  # N
    ft_torque: float = 0.01  # Nm
    gyro: float = 3e-3  # rad/s
    acc: float = 0.03  # m/s²

    @classmethod
    def none(cls) -> SensorNoise:
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class Reading:
    """What the robot's controller sees at one tick (plus the simulator's ground truth)."""

    t: float
    q: np.ndarray  # encoders
    current: np.ndarray
    ft: np.ndarray  # wrench of the sole plate on the ankle, sensor frame [f; m]
    gyro: np.ndarray
    acc: np.ndarray
    # ground truth
    q_true: np.ndarray
    dq_true: np.ndarray
    ddq_true: np.ndarray
    tau: np.ndarray  # link-side joint torque
    tau_motor: np.ndarray
    contact: np.ndarray  # contact wrench of the floor on the sole, world axes, at the sole centre


class PositionControlledLeg:
    """MuJoCo TALOS right leg with position-controlled actuators (see module docstring).

    ``model_error``: relative std of the seeded perturbation of link masses, inertias (and
    0.5 cm × model_error/0.05 CoM shifts) of the *simulated* leg, so that the controller's
    nominal Pinocchio model (:attr:`robot`) is not exact.
    """

    def __init__(
        self,
        setup: str = "air",
        actuators: ActuatorParams | None = None,
        noise: SensorNoise | None = None,
        control_dt: float = 1e-3,
        substeps: int = 2,
        model_error: float = 0.05,
        seed: int = 0,
        q0: np.ndarray | None = None,
        floor_offset: float = 0.0,
    ) -> None:
        import mujoco

        if setup not in ("air", "contact"):
            raise DataError(f"setup must be 'air' or 'contact', got '{setup}'")
        self.setup = setup
        self.act = actuators or ActuatorParams()
        self.noise = noise if noise is not None else SensorNoise()
        self.control_dt = float(control_dt)
        self.substeps = int(substeps)
        self.model_error = float(model_error)
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.robot = talos_right_leg()
        self.joint_names = JOINTS
        floor = None
        if setup == "contact":
            d = self.robot.model.createData()
            pin.framesForwardKinematics(self.robot.model, d, Q_CONTACT)
            floor = float(d.oMf[self.robot.frame_id(SOLE_FRAME)].translation[2]) - floor_offset
        self.floor_height = floor
        spec = right_leg_mjspec(self.act.rotor_inertia, floor_height=floor, timestep=self.control_dt / self.substeps)
        self.m = spec.compile()
        self._perturb(self.model_error)
        self.d = mujoco.MjData(self.m)
        self._mj = mujoco
        self._plate_body = self.m.body("right_foot_plate").id
        self._sole_site = self.m.site("sole").id
        self._floor_geom = self.m.geom("floor").id if floor is not None else -1
        self._adr = {n: int(self.m.sensor_adr[self.m.sensor(n).id]) for n in ("ft_force", "ft_torque", "gyro", "acc")}
        self.q_cmd = np.zeros(6)
        self._comp = self.act.friction_compensation * self.act.coulomb
        self._inv_vc = 1.0 / self.act.compensation_velocity
        self._noise_block = np.empty((0, 24))
        self._noise_i = 0
        self._scale = np.r_[np.full(6, self.noise.encoder), np.full(6, self.noise.current), np.full(3, self.noise.ft_force),
                            np.full(3, self.noise.ft_torque), np.full(3, self.noise.gyro), np.full(3, self.noise.acc)]
        self._inv_k1 = 1.0 / (self.act.gear_ratio * self.act.torque_constant)
        self._fr = int(self._mj.mjtConstraint.mjCNSTR_FRICTION_DOF)
        self._lim = int(self._mj.mjtConstraint.mjCNSTR_LIMIT_JOINT)
        self.reset(q0 if q0 is not None else (Q_CONTACT if setup == "contact" else Q_AIR))

    def _perturb(self, rel: float) -> None:
        if rel <= 0:
            return
        rng = np.random.default_rng(10_000 + self.seed)
        for b in range(1, self.m.nbody):
            if self.m.body_mass[b] <= 0.02:
                continue
            s = 1.0 + rel * rng.standard_normal()
            self.m.body_mass[b] *= s
            self.m.body_inertia[b] *= s * (1.0 + 0.5 * rel * rng.standard_normal(3))
            self.m.body_ipos[b] += (0.1 * rel) * rng.standard_normal(3)

    # ---- state ------------------------------------------------------------------------------
    def reset(self, q0: np.ndarray, settle: float = 0.0, dq0: np.ndarray | None = None) -> None:
        """Start at rest at ``q0`` (or with joint velocities ``dq0``); ``settle`` seconds of
        position control at q0 follow, then the clock restarts at 0."""
        mj = self._mj
        mj.mj_resetData(self.m, self.d)
        self.d.qpos[:] = np.asarray(q0, float)
        self.d.qvel[:] = 0.0 if dq0 is None else np.asarray(dq0, float)
        mj.mj_forward(self.m, self.d)
        self.q_cmd = np.asarray(q0, float).copy()
        self.t = 0.0
        if settle > 0:
            for _ in range(round(settle / self.control_dt)):
                self.step(self.q_cmd)
            self.t = 0.0

    def _drive(self, q_cmd: np.ndarray) -> np.ndarray:
        a, d = self.act, self.d
        v = d.qvel
        e = q_cmd - d.qpos
        dz = np.copysign(np.maximum(np.abs(e) - a.dead_zone, 0.0), e)
        tm = a.stiffness * dz - a.damping * v + self._comp * np.tanh(v * self._inv_vc)
        tm = np.minimum(np.maximum(tm, -a.torque_limit), a.torque_limit)
        self.m.dof_frictionloss[:] = a.coulomb + a.load_friction * np.abs(tm)
        d.qfrc_applied[:] = tm - a.viscous * v
        return tm

    def step(self, q_cmd: np.ndarray, wrench: np.ndarray | None = None) -> Reading:
        """Hold ``q_cmd`` for one control period; ``wrench``: external [f; m] (world axes) on
        the sole plate at the sole centre. Returns the sensor readings of this tick."""
        mj, m, d = self._mj, self.m, self.d
        q_cmd = np.asarray(q_cmd, float)
        if q_cmd.shape != (6,) or not np.all(np.isfinite(q_cmd)):
            raise ShapeMismatchError(f"q_cmd must be 6 finite angles, got {q_cmd}")
        self.q_cmd = q_cmd
        if wrench is not None:
            w = np.asarray(wrench, float)
            com = d.xipos[self._plate_body]
            sole = d.site_xpos[self._sole_site]
            d.xfrc_applied[self._plate_body, :3] = w[:3]
            d.xfrc_applied[self._plate_body, 3:] = w[3:] + np.cross(sole - com, w[:3])
        else:
            d.xfrc_applied[self._plate_body] = 0.0
        for _ in range(self.substeps):
            q0, v0 = d.qpos.copy(), d.qvel.copy()
            tm = self._drive(q_cmd)
            mj.mj_step(m, d)
        self.t += self.control_dt
        return self._reading(q0, v0, tm)

    def _noise(self) -> np.ndarray:
        if self._noise_i >= self._noise_block.shape[0]:
            self._noise_block = self.rng.standard_normal((4096, 24)) * self._scale
            self._noise_i = 0
        z = self._noise_block[self._noise_i]
        self._noise_i += 1
        return z

    def _reading(self, q, v, tm) -> Reading:
        d, a = self.d, self.act
        sd = d.sensordata
        af, at, ag, aa = self._adr["ft_force"], self._adr["ft_torque"], self._adr["gyro"], self._adr["acc"]
        # MuJoCo: wrench of the parent (ankle) on the plate, site frame -> negate (plate on ankle)
        ft = np.empty(6)
        ft[:3] = sd[af: af + 3]
        ft[3:] = sd[at: at + 3]
        ft *= -1.0
        qacc = d.qacc.copy()
        tau_j = np.zeros(6)  # friction and joint-limit constraint torques on each dof
        n = d.nefc
        if n:
            types = d.efc_type[:n]
            sel = (types == self._fr) | (types == self._lim)
            if sel.any():
                J = d.efc_J[: n * 6].reshape(n, 6) if d.efc_J.size >= n * 6 else None
                if J is not None:
                    tau_j = J[sel].T @ d.efc_force[:n][sel]
        tau = tm - a.viscous * v + tau_j - a.rotor_inertia * qacc
        z = self._noise()
        return Reading(
            t=self.t,
            q=q + z[0:6],
            current=tm * self._inv_k1 + z[6:12],
            ft=ft + z[12:18],
            gyro=sd[ag: ag + 3] + z[18:21],
            acc=sd[aa: aa + 3] + z[21:24],
            q_true=q, dq_true=v, ddq_true=qacc, tau=tau, tau_motor=tm.copy(), contact=self._contact_wrench(),
        )

    def _contact_wrench(self) -> np.ndarray:
        if self._floor_geom < 0 or self.d.ncon == 0:
            return np.zeros(6)
        mj, m, d = self._mj, self.m, self.d
        sole = d.site_xpos[self._sole_site]
        w = np.zeros(6)
        f6 = np.zeros(6)
        for c in range(d.ncon):
            con = d.contact[c]
            if self._floor_geom not in (con.geom1, con.geom2):
                continue
            mj.mj_contactForce(m, d, c, f6)
            R = con.frame.reshape(3, 3)  # rows: normal, tangent1, tangent2 (world)
            f = R.T @ f6[:3]  # force on geom2 from geom1, world axes
            if con.geom2 == self._floor_geom:  # we want the force of the floor on the sole
                f = -f
            w[:3] += f
            w[3:] += np.cross(con.pos - sole, f)
        return w


@dataclass
class SimLog:
    """Arrays (N, ...) of one simulated run, one row per control tick."""

    t: np.ndarray
    q: np.ndarray
    q_cmd: np.ndarray
    current: np.ndarray
    ft: np.ndarray
    gyro: np.ndarray
    acc: np.ndarray
    q_true: np.ndarray
    dq_true: np.ndarray
    ddq_true: np.ndarray
    tau: np.ndarray
    tau_motor: np.ndarray
    contact: np.ndarray
    extras: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return self.t.size

    def to_trajectory(self) -> Trajectory:
        """Encoder log as a :class:`Trajectory` (tau = true link torque; sensors in extras)."""
        return Trajectory(
            self.t, self.q, JOINTS, tau=self.tau,
            extras={"q_cmd": self.q_cmd, "current": self.current, "ft": self.ft, "gyro": self.gyro, "acc": self.acc,
                    "contact": self.contact},
            units={"q": "rad", "tau": "Nm (true link-side torque)", "ft": "N, Nm (sensor frame)", "acc": "m/s^2"},
            source="<simulated talos right leg>",
        )

    @staticmethod
    def concatenate(logs: list[SimLog]) -> SimLog:
        names = [f for f in SimLog.__dataclass_fields__ if f != "extras"]
        out = {}
        ts = []
        for lg in logs:
            if not ts:
                ts.append(lg.t.copy())
            else:
                dt = lg.t[1] - lg.t[0] if len(lg) > 1 else (ts[-1][1] - ts[-1][0] if len(ts[-1]) > 1 else 0.0)
                ts.append(lg.t - lg.t[0] + ts[-1][-1] + dt)
        out["t"] = np.concatenate(ts)
        for n in names[1:]:
            out[n] = np.concatenate([getattr(lg, n) for lg in logs])
        return SimLog(**out)


def simulate(
    sim: PositionControlledLeg,
    command: Callable[[int, Reading | None], np.ndarray],
    n_steps: int,
    wrench: Callable[[int], np.ndarray | None] | None = None,
    stop: Callable[[Reading], bool] | None = None,
) -> SimLog:
    """Run ``n_steps`` control ticks: ``command(k, last_reading)`` returns q_cmd for tick k
    (``last_reading`` is None at k = 0); ``wrench(k)`` an optional external foot wrench.
    ``stop(reading)`` may end the run early (e.g. a joint at its limit)."""
    rows: list[Reading] = []
    cmds = []
    last = None
    for k in range(int(n_steps)):
        qc = command(k, last)
        last = sim.step(qc, None if wrench is None else wrench(k))
        rows.append(last)
        cmds.append(np.array(qc, float))
        if stop is not None and stop(last):
            break
    get = lambda name: np.array([getattr(r, name) for r in rows])
    return SimLog(
        t=get("t"), q=get("q"), q_cmd=np.array(cmds), current=get("current"), ft=get("ft"), gyro=get("gyro"),
        acc=get("acc"), q_true=get("q_true"), dq_true=get("dq_true"), ddq_true=get("ddq_true"), tau=get("tau"),
        tau_motor=get("tau_motor"), contact=get("contact"),
    )


def leg_estimator(robot, unknown_wrench_frame: str | None = None) -> JointTorqueEstimator:
    """The F/T + IMU joint-torque estimator of the simulated leg (nominal model)."""
    return JointTorqueEstimator(robot, [FTSensor("right_ankle", FT_FRAME, plate_inertia())], ImuSpec(IMU_FRAME),
                                unknown_wrench_frame=unknown_wrench_frame)



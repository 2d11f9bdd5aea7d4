"""A fixed-base arm pushed at a frame: logs with a known external torque (Pinocchio-integrated).

The true robot (a :class:`~.synthetic.TruthModel`: inertials, armature, viscous and smooth
Coulomb friction fc·tanh(v/ε)) tracks a Fourier reference with PD + gravity compensation of
the *nominal* model. Pushes are forces F(t) at a frame (LOCAL_WORLD_ALIGNED), each a
raised cosine F_peak sin²(π (t − t₀)/(t₁ − t₀)) on [t₀, t₁]. Forward dynamics:

    M(q) v̇ = τ − h(q, v) − τ_f(v) + J(q)ᵀ [F; 0],       (Pinocchio crba / nonLinearEffects)

integrated by semi-implicit Euler at ``sim_rate`` with τ held over a step, logged every
``sim_rate / log_rate`` steps (q, v, τ of the same instant, optional white noise). The
truth returned beside the log is τ_ext = Jᵀ F (N, nv) and F (N, 3) at the logged instants.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.errors import SensorlessError
from sensorless.excitation import random_fourier
from sensorless.robot import Robot
from sensorless.testing import NoiseSpec, TruthModel, add_white_noise

__all__ = ["Push", "PushTruth", "log_decimation", "noisy_joint_log", "push_torques", "pushed_arm_scenario", "simulate_pushes"]


@dataclass(frozen=True)
class Push:
    """Raised-cosine force ``peak`` (3,) [N] at ``frame`` between ``start`` and ``end`` [s]."""

    start: float
    end: float
    peak: tuple[float, float, float]
    frame: str

    def force(self, t: float) -> np.ndarray:
        if not (self.start <= t <= self.end):
            return np.zeros(3)
        return np.asarray(self.peak, float) * np.sin(np.pi * (t - self.start) / (self.end - self.start)) ** 2


@dataclass
class PushTruth:
    t: np.ndarray
    tau_ext: np.ndarray  # (N, nv)
    force: np.ndarray  # (N, 3) sum of the pushes' forces
    active: np.ndarray  # (N,) bool: a push is on
    pushes: tuple[Push, ...]
    coulomb_velocity: float


def simulate_pushes(
    truth: TruthModel,
    nominal: Robot,
    pushes: Sequence[Push],
    *,
    duration: float = 10.0,
    sim_rate: float = 1000.0,
    log_rate: float = 1000.0,
    seed: int = 0,
    coulomb_velocity: float = 0.05,
    noise: NoiseSpec | None = None,
    kp: float = 400.0,
    kd: float = 40.0,
    base_freq: float = 0.1,
) -> tuple[Trajectory, PushTruth]:
    """Simulate the pushed arm; return (log, truth). See the module docstring.

    ``noise``: white noise on the logged joint signals (its ``q``, ``v``, ``tau``); None: none."""
    decim = log_decimation(sim_rate, log_rate)
    r = truth.robot
    if r.floating_base or r.n_actuated != r.nv:
        raise SensorlessError(f"{r.name}: the pushed-arm simulation needs a fixed-base, fully actuated arm")
    model = r.model.copy()
    model.armature[r.actuated_v_indices] = truth.armature
    data = model.createData()
    nom_model = nominal.model
    nom_data = nom_model.createData()
    fids = {p.frame: r.frame_id(p.frame) for p in pushes}
    ref = random_fourier(r, rng=seed, base_freq=base_freq, max_velocity=1.0, max_acceleration=3.0)
    dt = 1.0 / sim_rate
    n_steps = int(round(duration * sim_rate))
    t_ref = np.arange(n_steps + 1) * dt
    Qr, Vr, _ = ref.evaluate(t_ref)
    q, v = r.full_configuration(Qr[:1])[0], Vr[0].copy()
    act = r.actuated_v_indices
    logs = {k: [] for k in ("t", "q", "v", "tau", "ext", "F", "on")}
    for k in range(n_steps + 1):
        t = k * dt
        tau = pin.computeGeneralizedGravity(nom_model, nom_data, q)[act] + kp * (Qr[k] - q[act]) + kd * (Vr[k] - v[act])
        ext, F_tot, on = push_torques(model, data, q, pushes, fids, t)
        if k % decim == 0:
            for key, val in zip(logs, (t, q[act], v[act], tau, ext, F_tot, on)):
                logs[key].append(np.copy(val))
        if k == n_steps:
            break
        fric = np.zeros(r.nv)
        fric[act] = truth.fv * v[act] + truth.fc * np.tanh(v[act] / coulomb_velocity) + truth.offset
        full = np.zeros(r.nv)
        full[act] = tau
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        a = np.linalg.solve(M, full - pin.nonLinearEffects(model, data, q, v) - fric + ext)
        v = v + dt * a
        q = pin.integrate(model, q, dt * v)
    arr = {k: np.array(v_) for k, v_ in logs.items()}
    traj = noisy_joint_log(arr, r, noise, seed, f"<pushed {r.name} seed={seed}>")
    return traj, PushTruth(arr["t"], arr["ext"], arr["F"], arr["on"].astype(bool), tuple(pushes), coulomb_velocity)


def log_decimation(sim_rate: float, log_rate: float) -> int:
    """Simulation steps per logged sample; SensorlessError unless ``sim_rate`` is an integer multiple of ``log_rate``."""
    ratio = sim_rate / log_rate
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise SensorlessError(f"sim_rate ({sim_rate}) must be an integer multiple of log_rate ({log_rate})")
    return int(round(ratio))


def push_torques(model, data, q: np.ndarray, pushes: Sequence[Push], fids: dict, t: float):
    """(τ_ext = Σ Jᵀ F over the pushes active at ``t`` (linear Jacobian, LOCAL_WORLD_ALIGNED), total F, any push on)."""
    ext, F_tot, on = np.zeros(model.nv), np.zeros(3), False
    for p in pushes:
        F = p.force(t)
        if np.any(F):
            on = True
            J = pin.computeFrameJacobian(model, data, q, fids[p.frame], pin.LOCAL_WORLD_ALIGNED)
            ext += J[:3].T @ F
            F_tot += F
    return ext, F_tot, on


def noisy_joint_log(arr: dict, robot: Robot, noise: NoiseSpec | None, seed: int, source: str,
                    t0: float = 0.0) -> Trajectory:
    """The logged joint signals ``arr`` (t, q, v, tau) with white noise (``noise``; None: none, seeded
    by ``seed + 1``), stamps from ``t0``."""
    rng = np.random.default_rng(seed + 1)
    noise = NoiseSpec.none() if noise is None else noise
    return Trajectory(
        t=t0 + arr["t"], q=add_white_noise(arr["q"], noise.q, rng), v=add_white_noise(arr["v"], noise.v, rng),
        tau=add_white_noise(arr["tau"], noise.tau, rng), joint_names=robot.joint_names, source=source,
        units={"t": "s", "q": "rad", "v": "rad/s", "tau": "N·m"},
    )


def pushed_arm_scenario(seed: int = 0, *, robot: str = "ur5", frame: str = "tool0", train_duration: float = 20.0,
                        ) -> tuple[Trajectory, Trajectory, PushTruth]:
    """(training log, pushed log, truth) of a perturbed arm (truth ``perturbed_truth(rng=seed + 1)``)
    tracking Fourier references: a push-free training log of ``train_duration`` s and a 19 s log
    pushed twice at ``frame``, (0, 0, −25) N over 12–12.8 s and (15, −10, 0) N over 16–16.5 s (the
    first 10 s are contact-free); 200 Hz, noise σ_q = 1e-4 rad, σ_v = 1e-2 rad/s, σ_τ = 0.2 N·m."""
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth

    nom = load_robot(robot)
    truth = perturbed_truth(nom, rng=seed + 1)
    noise = dict(noise=NoiseSpec(q=1e-4, v=1e-2, tau=0.2), log_rate=200.0)
    train, _ = simulate_pushes(truth, nom, [], duration=train_duration, seed=seed + 10, base_freq=0.05, **noise)
    pushes = [Push(12.0, 12.8, (0.0, 0.0, -25.0), frame), Push(16.0, 16.5, (15.0, -10.0, 0.0), frame)]
    log, gt = simulate_pushes(truth, nom, pushes, duration=19.0, seed=seed + 11, **noise)
    return train, log, gt

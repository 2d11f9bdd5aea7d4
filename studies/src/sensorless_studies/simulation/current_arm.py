"""Simulated current-logged arm runs (motor currents, jittery ~100 Hz clock, idle ends),
with an optional Stribeck-friction "true" robot and a payload at a frame.

Used by ``sensorless example current-arm`` (docs/arm.md §6) and the real-arm acceptance
experiment (:mod:`sensorless_studies.benchmarks.real_arm`). A run (:func:`simulate`) is a table with
``time, pos_<joint>..., vel_<joint>..., i_<joint>...``: the true motion (a random Fourier
excitation blended in and out with quintic ramps between idle segments) sampled at jittered
instants, logged with stamps that repeat now and then; i = τ/K + noise; q and v with
white noise.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pinocchio as pin

from sensorless.excitation import random_fourier
from sensorless.robot import Robot, load_robot
from sensorless.testing import perturbed_truth

__all__ = ["StribeckTruth", "UR5_GAINS", "drive_gains_for", "simulate", "stribeck_truth", "truth_model", "with_payload"]

#: Drive gains K [N·m/A] per joint (joint side: torque constant × gear ratio), UR5-like.
UR5_GAINS = (10.0, 10.7, 9.6, 4.3, 4.1, 4.0)
T0 = 1_712_345_678.0  # Unix time of the first sample [s]


def _ramp(t: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic smoothstep s(t/T) on [0, T] and its first two time derivatives."""
    x = np.clip(t / T, 0.0, 1.0)
    inside = (t > 0) & (t < T)
    s = x**3 * (10 - 15 * x + 6 * x**2)
    ds = np.where(inside, 30 * x**2 * (1 - x) ** 2 / T, 0.0)
    dds = np.where(inside, 60 * x * (1 - x) * (1 - 2 * x) / T**2, 0.0)
    return s, ds, dds


@dataclasses.dataclass
class StribeckTruth:
    """A true robot whose joints have Stribeck friction (``base`` carries no Coulomb term):

        τ_f = fc sgn v + (fs − fc) exp(−(v/vs)²) sgn v + fv v + o   (sgn 0 = 0: no friction at rest).
    """

    base: object  # sensorless_studies.simulation.TruthModel with fc = 0
    fc: np.ndarray
    fs: np.ndarray
    vs: np.ndarray

    @property
    def robot(self):
        return self.base.robot

    def torques(self, Q, V, A) -> np.ndarray:
        v = V[:, self.robot.actuated_v_indices]
        s = np.sign(v)
        return self.base.torques(Q, V, A) + self.fc * s + (self.fs - self.fc) * np.exp(-((v / self.vs) ** 2)) * s


def stribeck_truth(truth, seed: int = 0, scale: float = 1.0) -> StribeckTruth:
    """Stribeck friction on a :func:`perturbed_truth`: fc from it (× ``scale``), fs = U(1.3, 2)·fc,
    vs = U(0.02, 0.1) rad/s."""
    rng = np.random.default_rng(seed + 7919)
    n = len(truth.fc)
    fc = truth.fc * scale
    return StribeckTruth(dataclasses.replace(truth, fc=np.zeros(n)), fc, fc * rng.uniform(1.3, 2.0, n),
                         rng.uniform(0.02, 0.1, n))


def with_payload(truth, frame: str, mass: float, com=(0.06, 0.02, 0.05)):
    """The same true robot carrying a point mass ``mass`` [kg] at ``com`` in ``frame``."""
    inner = truth.base if isinstance(truth, StribeckTruth) else truth
    r = inner.robot
    model = r.model.copy()
    f = model.frames[model.getFrameId(frame)]
    model.inertias[f.parentJoint] = model.inertias[f.parentJoint] + f.placement.act(
        pin.Inertia(float(mass), np.asarray(com, dtype=float), np.zeros((3, 3))))
    loaded = dataclasses.replace(inner, robot=Robot(model, name=r.name + "_payload", source=r.source,
                                                    actuated_joints=r.actuated_joints))
    return dataclasses.replace(truth, base=loaded) if isinstance(truth, StribeckTruth) else loaded


def truth_model(robot_name: str = "ur5", seed: int = 0, stribeck: bool = False, friction_scale: float = 1.0):
    """The robot and its 'true' model (seeded), shared by the train and test logs."""
    robot = load_robot(robot_name)
    truth = perturbed_truth(robot, rng=seed)
    return robot, (stribeck_truth(truth, seed, friction_scale) if stribeck else truth)


def drive_gains_for(robot) -> np.ndarray:
    """UR-like drive gains: :data:`UR5_GAINS` (× 1.3 on a UR10), 8 on other robots."""
    if robot.n_actuated <= len(UR5_GAINS):
        return np.asarray(UR5_GAINS[: robot.n_actuated]) * (1.3 if "ur10" in robot.name else 1.0)
    return np.full(robot.n_actuated, 8.0)


def simulate(
    robot, truth, gains, *, seed: int, rate: float = 100.0, motion: float = 20.0, idle_start: float = 2.0,
    idle_end: float = 3.0, ramp: float = 2.0, jitter: float = 0.15, duplicates: int = 3,
    current_noise: float = 0.01, q_noise: float = 1e-4, v_noise: float = 1e-3, motion_seed: int | None = None,
    creep: "dict[str, float] | None" = None, moving: "list[str] | None" = None,
) -> pd.DataFrame:
    """One current-logged run as a table (columns as in the module docstring). ``motion_seed``:
    the excitation's own seed (default ``seed``), so two runs can share a trajectory. ``creep``:
    {joint: speed [rad/s]} added to those joints' velocity throughout (q drifts by speed · t): in the
    idle segments they creep under load, with the friction of that speed. ``moving``: only these joints
    are excited (the others hold their centre position; a single-joint calibration log)."""
    rng = np.random.default_rng(seed)
    frng = rng if motion_seed is None else np.random.default_rng(motion_seed)
    fourier = random_fourier(robot, rng=frng, position_fraction=0.3, max_velocity=1.0, max_acceleration=4.0)
    n = int(round((idle_start + motion + idle_end) * rate))
    period = 1.0 / rate
    true_t = np.maximum.accumulate(np.arange(n) * period + rng.normal(0.0, jitter * period, n))  # sampling instants
    stamp = true_t.copy()
    for k in rng.choice(np.arange(1, n), size=duplicates, replace=False):
        stamp[k] = stamp[k - 1]  # the clock was read late: a stamp repeated
    # excitation blended in and out with ramps: q = q_c + w (f - q_c), w = s(τ) s(motion - τ)
    tau_m = true_t - idle_start
    f, fd, fdd = fourier.evaluate(np.clip(tau_m, 0.0, motion))
    s1, d1, dd1 = _ramp(tau_m, ramp)
    s2, d2, dd2 = _ramp(motion - tau_m, ramp)
    w = s1 * s2
    dw = d1 * s2 - s1 * d2
    ddw = dd1 * s2 - 2 * d1 * d2 + s1 * dd2
    qc = fourier.q0
    if moving is not None:
        still = [k for k, j in enumerate(robot.joint_names) if j not in moving]
        f, fd, fdd = f.copy(), fd.copy(), fdd.copy()
        f[:, still], fd[:, still], fdd[:, still] = qc[still], 0.0, 0.0
    dev = f - qc
    q = qc + w[:, None] * dev
    v = dw[:, None] * dev + w[:, None] * fd
    a = ddw[:, None] * dev + 2 * dw[:, None] * fd + w[:, None] * fdd
    for j, speed in (creep or {}).items():
        k = list(robot.joint_names).index(j)
        q[:, k] += speed * true_t
        v[:, k] += speed
    tau = truth.torques(robot.full_configuration(q), robot.full_velocity(v), robot.full_velocity(a))
    K = np.asarray(gains, dtype=float)
    current = tau / K + rng.normal(0.0, current_noise, tau.shape)
    names = robot.joint_names
    table = {"time": T0 + stamp}
    table.update({f"pos_{j}": q[:, k] + rng.normal(0.0, q_noise, n) for k, j in enumerate(names)})
    table.update({f"vel_{j}": v[:, k] + rng.normal(0.0, v_noise, n) for k, j in enumerate(names)})
    table.update({f"i_{j}": current[:, k] for k, j in enumerate(names)})
    return pd.DataFrame(table)



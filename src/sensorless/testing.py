"""Synthetic data for tests: fixed-base logs with known ground truth, computed independently of the regressor
(no simulator; the MuJoCo scenes and studies are the separate ``sensorless-studies`` package).

Torques come from Pinocchio's RNEA on the true model plus the true joint terms

    τ = rnea(q, v, v̇) + Ia v̇ + fv v + fc sgn(v) + o  (+ Gaussian noise σ)

so identification tests compare against physics, not against the regressor itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import pinocchio as pin

from .data.trajectory import Trajectory
from .robot import Robot

__all__ = ["NoiseSpec", "TruthModel", "add_white_noise", "map_body_inertias", "perturbed_truth", "streamed_fourier_log",
           "synthetic_trajectory"]


@dataclass
class TruthModel:
    """A robot with known inertial parameters and joint terms (per actuated joint)."""

    robot: Robot
    fv: np.ndarray
    fc: np.ndarray
    offset: np.ndarray
    armature: np.ndarray

    def torques(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Actuated-joint torques (N, n_actuated) by RNEA + joint terms."""
        r = self.robot
        model = r.model.copy()
        model.armature[:] = 0.0
        data = model.createData()
        act = r.actuated_v_indices
        tau = np.empty((Q.shape[0], r.n_actuated))
        for i in range(Q.shape[0]):
            tau[i] = pin.rnea(model, data, Q[i], V[i], A[i])[act]
        v, a = V[:, act], A[:, act]
        return tau + self.armature * a + self.fv * v + self.fc * np.sign(v) + self.offset

    def parameters(self, joint_terms=("fv", "fc", "offset", "armature")) -> np.ndarray:
        """Standard parameter vector in the layout of :class:`~sensorless.regressor.ModelStructure`."""
        per_joint = np.stack([getattr(self, t) for t in joint_terms], axis=1) if joint_terms else np.zeros((0,))
        return np.concatenate([self.robot.inertial_parameters(), per_joint.ravel()])


def map_body_inertias(robot: Robot, new_inertia: Callable[[pin.Inertia], pin.Inertia]) -> Robot:
    """A copy ``<name>_truth`` of ``robot`` whose every massive body's inertia ``I`` is
    ``new_inertia(I)`` (called body by body in joint order; massless bodies are kept)."""
    model = robot.model.copy()
    for j in range(1, model.njoints):
        if model.inertias[j].mass > 0:
            model.inertias[j] = new_inertia(model.inertias[j])
    return Robot(model, name=robot.name + "_truth", source=robot.source, actuated_joints=robot.actuated_joints)


def perturbed_truth(
    robot: Robot,
    *,
    rng: np.random.Generator | int = 0,
    mass_scale: float = 0.2,
    com_shift: float = 0.02,
    friction: bool = True,
    armature: float | None = 0.05,
) -> TruthModel:
    """A physically consistent 'true' robot near the nominal one, with friction.

    Each body's mass is scaled by U(1 ± mass_scale), its CoM shifted by up to ``com_shift`` m
    and its rotational inertia about the CoM scaled by the same factor (stays consistent).
    """
    rng = np.random.default_rng(rng)

    def scaled(I: pin.Inertia) -> pin.Inertia:
        s = 1.0 + mass_scale * rng.uniform(-1, 1)
        return pin.Inertia(I.mass * s, I.lever + rng.uniform(-com_shift, com_shift, 3), I.inertia * s)

    true = map_body_inertias(robot, scaled)
    n = robot.n_actuated
    fv = rng.uniform(0.05, 0.5, n) if friction else np.zeros(n)
    fc = rng.uniform(0.1, 1.0, n) if friction else np.zeros(n)
    off = rng.uniform(-0.3, 0.3, n) if friction else np.zeros(n)
    ia = np.full(n, armature) * rng.uniform(0.5, 1.5, n) if armature else np.zeros(n)
    return TruthModel(true, fv, fc, off, ia)


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


def add_white_noise(x: np.ndarray, sigma: float | np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``x + σ ⊙ n`` with n ~ N(0, I) drawn from ``rng`` (a new array; nothing drawn when every σ is 0)."""
    if np.any(np.asarray(sigma) > 0):
        return x + rng.normal(size=x.shape) * sigma
    return x.copy()


def synthetic_trajectory(
    truth: TruthModel,
    motion: Trajectory,
    *,
    noise_std: float | np.ndarray = 0.0,
    rng: np.random.Generator | int = 0,
) -> Trajectory:
    """Fill ``motion`` (q, v, a of a fixed-base robot) with true torques + noise."""
    rng = np.random.default_rng(rng)
    r = truth.robot
    Q = r.full_configuration(motion.q)
    V = r.full_velocity(motion.v)
    A = r.full_velocity(motion.a)
    tau = add_white_noise(truth.torques(Q, V, A), noise_std, rng)
    full = np.zeros((len(motion), len(r.joint_names)))
    cols = [r.joint_names.index(j) for j in r.actuated_joints]
    full[:, cols] = tau
    return motion.with_(tau=full, source=f"<synthetic {r.name}>")


def streamed_fourier_log(
    truth: TruthModel,
    fourier,
    *,
    rate: float,
    n_samples: int,
    chunk: int = 10_000,
    noise_std: float = 0.0,
    rng: np.random.Generator | int = 0,
):
    """Yield a long synthetic Fourier log chunk by chunk (constant memory)."""
    rng = np.random.default_rng(rng)
    for start in range(0, n_samples, chunk):
        t = (start + np.arange(min(chunk, n_samples - start))) / rate
        q, v, a = fourier.evaluate(t)
        motion = Trajectory(t=t, q=q, v=v, a=a, joint_names=fourier.joint_names, source="<stream>")
        yield synthetic_trajectory(truth, motion, noise_std=noise_std, rng=rng)

"""Periodic excitation trajectories: finite Fourier series per joint (Swevers et al. 1997).

    q_j(t) = q0_j + Σ_{l=1..H} [ a_jl/(ω_l) sin(ω_l t) − b_jl/(ω_l) cos(ω_l t) ],  ω_l = 2π l f0

so v and v̇ are closed-form and the trajectory is periodic with period 1/f0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import ExcitationError
from ..robot import Robot

__all__ = ["FourierTrajectory", "random_fourier"]


@dataclass
class FourierTrajectory:
    """Fourier-series joint trajectory; ``a``, ``b`` have shape (n_joints, harmonics)."""

    base_freq: float
    a: np.ndarray
    b: np.ndarray
    q0: np.ndarray
    joint_names: tuple[str, ...]

    @property
    def period(self) -> float:
        return 1.0 / self.base_freq

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations at times t, each (N, n_joints)."""
        t = np.asarray(t, dtype=float)
        H = self.a.shape[1]
        w = 2 * np.pi * self.base_freq * np.arange(1, H + 1)  # (H,)
        wt = np.outer(t, w)  # (N, H)
        s, c = np.sin(wt), np.cos(wt)
        q = self.q0 + (s / w) @ self.a.T - (c / w) @ self.b.T
        v = c @ self.a.T + s @ self.b.T
        acc = -(s * w) @ self.a.T + (c * w) @ self.b.T
        return q, v, acc

    def sample(self, rate: float, duration: float | None = None, t0: float = 0.0) -> Trajectory:
        """A Trajectory (no torques) sampled at ``rate`` Hz for ``duration`` s (default one period)."""
        duration = self.period if duration is None else duration
        t = t0 + np.arange(int(round(duration * rate))) / rate
        q, v, a = self.evaluate(t)
        return Trajectory(t=t, q=q, v=v, a=a, joint_names=self.joint_names, source="<fourier>")

    def to_dict(self) -> dict:
        return {
            "base_freq": self.base_freq,
            "a": self.a.tolist(),
            "b": self.b.tolist(),
            "q0": self.q0.tolist(),
            "joint_names": list(self.joint_names),
        }

    def bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Upper bounds on |q − q0|, |v| and |v̇| per joint (triangle inequality)."""
        H = self.a.shape[1]
        w = 2 * np.pi * self.base_freq * np.arange(1, H + 1)
        amp = np.hypot(self.a, self.b)
        return (amp / w).sum(axis=1), amp.sum(axis=1), (amp * w).sum(axis=1)


def random_fourier(
    robot: Robot,
    *,
    harmonics: int = 5,
    base_freq: float = 0.1,
    rng: np.random.Generator | int = 0,
    position_fraction: float = 0.8,
    max_velocity: float | np.ndarray = 2.0,
    max_acceleration: float | np.ndarray = 10.0,
) -> FourierTrajectory:
    """Random Fourier coefficients scaled so the trajectory stays within limits.

    Centred mid-range; the worst-case amplitude bound is scaled to ``position_fraction``
    of each joint's half range (±π for unlimited joints), and velocity/acceleration bounds
    to ``max_velocity`` (capped by the model's velocity limit) and ``max_acceleration``.
    ``0 < position_fraction ≤ 1``: a larger fraction would leave the joint range.
    """
    if not (np.isfinite(position_fraction) and 0.0 < position_fraction <= 1.0):
        raise ExcitationError(f"position_fraction must be in (0, 1], got {position_fraction}")
    rng = np.random.default_rng(rng)
    n = len(robot.joint_names)
    lo, hi = robot.position_limits()
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    q0 = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo) * position_fraction
    vmax = np.minimum(np.broadcast_to(max_velocity, (n,)), np.where(robot.velocity_limits() > 0, robot.velocity_limits(), np.inf))
    amax = np.broadcast_to(max_acceleration, (n,))
    a = rng.normal(size=(n, harmonics))
    b = rng.normal(size=(n, harmonics))
    traj = FourierTrajectory(base_freq, a, b, q0, tuple(robot.joint_names))
    dq, dv, da = traj.bounds()
    scale = np.min(np.stack([half / dq, vmax / dv, amax / da]), axis=0)
    traj.a *= scale[:, None]
    traj.b *= scale[:, None]
    return traj

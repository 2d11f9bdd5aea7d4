"""Desired motions of the simulated surgical arm: multisines inside a joint box and
probing sequences (quintic segments), as reference q, q̇, q̈ on the simulation time grid."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from .surgical_arm import JAW_LENGTH, WRIST_LENGTH, direction_to_angles

__all__ = ["AMAX", "VMAX", "WORKSPACES", "DesiredMotion", "ProbeTarget", "multisine_motion", "probing_motion"]


@dataclass
class DesiredMotion:
    """Reference q, q̇, q̈ on the simulation time grid, shape (steps, n)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


WORKSPACES = {
    #           yaw          pitch         insertion     roll        wrist p      wrist y
    "full": ((-0.9, 0.9), (-0.7, 0.7), (0.02, 0.22), (-2.0, 2.0), (-1.2, 1.2), (-1.2, 1.2)),
    "split_train": ((-0.9, -0.15), (-0.7, 0.0), (0.02, 0.22), (-2.0, 2.0), (-1.2, 1.2), (-1.2, 1.2)),
    "split_test": ((0.15, 0.9), (0.0, 0.7), (0.02, 0.22), (-2.0, 2.0), (-1.2, 1.2), (-1.2, 1.2)),
    "trocar": ((-0.32, 0.32), (-0.32, 0.32), (0.09, 0.21), (-1.5, 1.5), (-0.8, 0.8), (-0.8, 0.8)),
}
#: default bounds of the desired joint speeds and accelerations (yaw, pitch, insertion [m], roll, wrist p, wrist y)
VMAX = np.array([0.8, 0.8, 0.12, 2.0, 2.0, 2.0])
AMAX = np.array([3.0, 3.0, 0.5, 8.0, 8.0, 8.0])


class ProbeTarget(Protocol):
    """What :func:`probing_motion` palpates (e.g. :class:`~.trocar.SphereObject`)."""

    def hit_distance(self, u: np.ndarray) -> float:
        """Distance along the unit ray ``u`` from the RCM (origin) to the surface (nan: miss)."""


def multisine_motion(
    box: Sequence[tuple[float, float]],
    duration: float,
    *,
    dt: float = 1e-3,
    rng: np.random.Generator | int = 0,
    components: int = 4,
    freq: tuple[float, float] = (0.05, 0.4),
    vmax: np.ndarray = VMAX,
    amax: np.ndarray = AMAX,
) -> DesiredMotion:
    """Sum of random sines per joint, scaled so q stays in ``box`` and |q̇|, |q̈| under the bounds.

    q_j(t) = c_j + Σ_k A_jk sin(2π f_jk t + φ_jk): aperiodic, rich, closed-form derivatives.
    """
    rng = np.random.default_rng(rng)
    lo, hi = np.array(box, dtype=float).T
    n = len(lo)
    f = rng.uniform(*freq, (n, components))
    ph = rng.uniform(0, 2 * np.pi, (n, components))
    A = rng.uniform(0.3, 1.0, (n, components))
    w = 2 * np.pi * f
    scale = np.min(np.stack([0.5 * (hi - lo) / A.sum(1), vmax / (A * w).sum(1), amax / (A * w * w).sum(1)]), axis=0)
    A *= scale[:, None]
    t = np.arange(int(round(duration / dt))) * dt
    arg = t[:, None, None] * w[None] + ph[None]
    q = 0.5 * (lo + hi) + np.einsum("jk,tjk->tj", A, np.sin(arg))
    v = np.einsum("jk,tjk->tj", A * w, np.cos(arg))
    a = -np.einsum("jk,tjk->tj", A * w * w, np.sin(arg))
    return DesiredMotion(t, q, v, a)


def _quintic(t: np.ndarray, times: np.ndarray, points: np.ndarray):
    """Stop-and-go minimum-jerk interpolation through waypoints (zero velocity at each)."""
    q = np.empty((len(t), points.shape[1]))
    v = np.zeros_like(q)
    a = np.zeros_like(q)
    q[:] = points[-1]
    for i in range(len(times) - 1):
        m = (t >= times[i]) & (t < times[i + 1])
        T = times[i + 1] - times[i]
        s = (t[m] - times[i]) / T
        dq = points[i + 1] - points[i]
        q[m] = points[i] + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, dq)
        v[m] = np.outer((30 * s**2 - 60 * s**3 + 30 * s**4) / T, dq)
        a[m] = np.outer((60 * s - 180 * s**2 + 120 * s**3) / T**2, dq)
    return q, v, a


def probing_motion(
    sphere: ProbeTarget,
    duration: float,
    *,
    dt: float = 1e-3,
    rng: np.random.Generator | int = 0,
    cone: float = 0.28,
    penetration: tuple[float, float] = (0.005, 0.02),
    slide: float = 0.06,
    wrist_box: Sequence[tuple[float, float]] = ((-1.2, 1.2), (-0.5, 0.5), (-0.5, 0.5)),
) -> DesiredMotion:
    """Repeated palpation of ``sphere``: hover → press (a few mm past the surface) → slide
    sideways while pressed → lift → next point, with slow roll/wrist motion throughout.

    Directions are drawn in a cone of half-angle ``cone`` around −z; the jaw tip depth
    along the shaft is ``q_insertion + WRIST_LENGTH + JAW_LENGTH`` at zero wrist angles.
    """
    rng = np.random.default_rng(rng)
    tool = WRIST_LENGTH + JAW_LENGTH
    times, pts = [0.0], []

    def pose(u, depth):
        y, p = direction_to_angles(u)
        return np.array([y, p, depth - tool])

    def direction():
        while True:
            th, ph = cone * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
            u = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)])
            if np.isfinite(sphere.hit_distance(u)):
                return u

    u = direction()
    pts.append(pose(u, sphere.hit_distance(u) - 0.02))
    while times[-1] < duration:
        s_hit = sphere.hit_distance(u)
        press = pose(u, s_hit + rng.uniform(*penetration))
        turn = rng.normal(size=2)
        y, p = press[0] + slide * turn[0] / np.linalg.norm(turn), press[1] + slide * turn[1] / np.linalg.norm(turn)
        u2 = np.array([-np.sin(p), np.cos(p) * np.sin(y), -np.cos(p) * np.cos(y)])
        s2 = sphere.hit_distance(u2)
        slid = np.array([y, p, (s2 if np.isfinite(s2) else s_hit) + rng.uniform(*penetration) - tool])
        lift = slid.copy()
        lift[2] -= rng.uniform(0.015, 0.03)
        for target, T in ((press, rng.uniform(0.5, 0.9)), (press, rng.uniform(0.1, 0.4)),
                          (slid, rng.uniform(0.6, 1.2)), (lift, rng.uniform(0.4, 0.7))):
            pts.append(target)
            times.append(times[-1] + T)
        u = direction()
        pts.append(pose(u, sphere.hit_distance(u) - rng.uniform(0.01, 0.025)))
        times.append(times[-1] + rng.uniform(0.6, 1.0))
    t = np.arange(int(round(duration / dt))) * dt
    q3, v3, a3 = _quintic(t, np.array(times), np.array(pts))
    wrist = multisine_motion(wrist_box, duration, dt=dt, rng=rng, vmax=VMAX[3:] * 0.5, amax=AMAX[3:] * 0.5)
    return DesiredMotion(t, np.hstack([q3, wrist.q]), np.hstack([v3, wrist.v]), np.hstack([a3, wrist.a]))

"""Reference protocols for the simulated position-controlled leg: increasing sinusoids,
quasi-static loading (in the air / in contact) and a stair-climbing-like swing."""

from __future__ import annotations

import numpy as np

from sensorless.errors import DataError

__all__ = ["Q_AIR", "Q_CONTACT", "SWING_DURATIONS", "SWING_WAYPOINTS", "increasing_sinusoids", "quasi_static_protocol", "swing_trajectory"]

Q_AIR = np.array([0.0, 0.0, -0.3, 0.6, -0.3, 0.0])
Q_CONTACT = np.array([0.0, 0.0, -0.45, 0.9, -0.45, 0.0])


def increasing_sinusoids(
    t: np.ndarray,
    q_mid: np.ndarray,
    a0: np.ndarray,
    a: np.ndarray,
    f: np.ndarray,
    a_max: np.ndarray | None = None,
) -> np.ndarray:
    """q_d(t) = q_mid + min(a0 + a t, a_max) sin(2π f t), per joint (arrays (6,))."""
    t = np.asarray(t, float)[:, None]
    amp = np.asarray(a0, float) + np.asarray(a, float) * t
    if a_max is not None:
        amp = np.minimum(amp, a_max)
    return np.asarray(q_mid, float) + amp * np.sin(2 * np.pi * np.asarray(f, float) * t)


def quasi_static_protocol(setup: str, duration: float, dt: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """High-torque, low-velocity data: returns (q_d (N, 6), foot wrench (N, 6) or None).

    Air: slow (≤ 0.1 Hz) joint sweeps while a slowly varying force of up to ~150 N (and
    ~10 Nm) pushes on the sole — the joints see large torques of both signs at low speed.
    Contact: the sole rests on the floor; slow extensions/flexions of hip, knee and ankle
    around ``Q_CONTACT`` press the foot into the floor (hundreds of N) and roll/yaw it.
    """
    rng = np.random.default_rng(seed)
    n = round(duration / dt)
    t = np.arange(n) * dt
    env = np.minimum(1.0, t / 2.0)[:, None]
    env = env * env * (3 - 2 * env)  # smooth 2-s start from the initial posture, no step
    ph = rng.uniform(0, 2 * np.pi, 6)
    if setup == "air":
        f = rng.uniform(0.03, 0.1, 6)
        amp = np.array([0.25, 0.15, 0.4, 0.5, 0.3, 0.15])
        q = Q_AIR + env * amp * np.sin(2 * np.pi * f * t[:, None] + ph)
        fw = rng.uniform(0.04, 0.12, 6)
        pw = rng.uniform(0, 2 * np.pi, 6)
        wamp = np.array([120.0, 120.0, 150.0, 8.0, 10.0, 6.0])
        w = env * wamp * np.sin(2 * np.pi * fw * t[:, None] + pw)
        return q, w
    if setup == "contact":
        f = rng.uniform(0.05, 0.12, 6)
        amp = np.array([0.02, 0.015, 0.03, 0.04, 0.03, 0.015])
        q = Q_CONTACT + env * amp * np.sin(2 * np.pi * f * t[:, None] + ph)
        press = 0.015 * env[:, 0] * (0.5 - 0.5 * np.cos(2 * np.pi * 0.07 * t))  # knee extension → press into the floor
        q[:, 3] -= press
        q[:, 2] += 0.5 * press
        q[:, 4] += 0.5 * press
        return q, None
    raise DataError(f"setup must be 'air' or 'contact', got '{setup}'")


# stair-climbing-like swing of the hanging leg: stance → lift → reach onto the step → place → back
SWING_WAYPOINTS = np.array([
    [0.0, 0.0, -0.30, 0.60, -0.30, 0.0],
    [0.08, -0.10, -1.05, 1.70, -0.55, 0.08],
    [0.10, -0.06, -1.25, 1.30, -0.15, 0.06],
    [0.04, -0.02, -0.85, 1.05, -0.25, 0.02],
    [0.0, 0.0, -0.30, 0.60, -0.30, 0.0],
])
SWING_DURATIONS = np.array([0.9, 0.7, 0.7, 1.0])


def swing_trajectory(dt: float, repeats: int = 1, hold: float = 0.5, speed: float = 1.0):
    """Minimum-jerk (quintic) joint trajectory through :data:`SWING_WAYPOINTS`, ``repeats``
    times, with ``hold`` seconds at rest before and after. Returns (t, q, dq, ddq)."""
    seg_q, seg_dq, seg_ddq = [], [], []

    def hold_block(q):
        n = round(hold / dt)
        return np.tile(q, (n, 1)), np.zeros((n, 6)), np.zeros((n, 6))

    for block in [hold_block(SWING_WAYPOINTS[0])]:
        seg_q.append(block[0]); seg_dq.append(block[1]); seg_ddq.append(block[2])
    for _ in range(int(repeats)):
        for i, T in enumerate(SWING_DURATIONS / speed):
            a, b = SWING_WAYPOINTS[i], SWING_WAYPOINTS[i + 1]
            n = round(T / dt)
            s = np.arange(n)[:, None] * dt / T
            p = 10 * s**3 - 15 * s**4 + 6 * s**5
            dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
            ddp = (60 * s - 180 * s**2 + 120 * s**3) / T**2
            seg_q.append(a + (b - a) * p); seg_dq.append((b - a) * dp); seg_ddq.append((b - a) * ddp)
    blk = hold_block(SWING_WAYPOINTS[-1])
    seg_q.append(blk[0]); seg_dq.append(blk[1]); seg_ddq.append(blk[2])
    q, dq, ddq = np.vstack(seg_q), np.vstack(seg_dq), np.vstack(seg_ddq)
    return np.arange(q.shape[0]) * dt, q, dq, ddq

"""Periodicity of a logged excitation (used to fold cross-validation on whole periods)."""

from __future__ import annotations

import numpy as np

from .trajectory import Trajectory

__all__ = ["excitation_period"]


def excitation_period(traj: Trajectory, *, min_period: float = 1.0, threshold: float = 0.95) -> float | None:
    """Period [s] of a repeated excitation: the shortest lag (from ``min_period`` to 60 % of
    the log) at which the autocorrelation of the joint positions (FFT, mean over joints)
    peaks above ``threshold``; None if there is none. Assumes a roughly uniform rate."""
    q = np.asarray(traj.q, dtype=float)
    n = q.shape[0]
    dt = traj.dt
    if n < 8 or not np.isfinite(dt) or dt <= 0:
        return None
    x = q - q.mean(axis=0)
    var = (x**2).mean(axis=0)
    x, var = x[:, var > 0], var[var > 0]
    if x.shape[1] == 0:
        return None
    f = np.fft.rfft(x, 2 * n, axis=0)
    ac = np.fft.irfft(np.abs(f) ** 2, axis=0)[:n] / (n - np.arange(n))[:, None] / var
    lo, hi = max(int(np.ceil(min_period / dt)), 1), int(0.6 * n)
    if hi <= lo + 1:
        return None
    r = ac[lo - 1 : hi + 1].mean(axis=1)
    peak = (r[1:-1] >= r[:-2]) & (r[1:-1] >= r[2:]) & (r[1:-1] >= threshold)
    k = np.flatnonzero(peak)
    return float((lo + k[0]) * dt) if k.size else None  # the shortest period

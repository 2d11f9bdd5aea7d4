"""The time lag between two runs of one trajectory, from their joint positions.

Two logs of the same commanded motion recorded at different times start their excitation at
different instants (seconds apart when an operator starts each run by hand). Measured from
each log's first sample, ``q_load(τ) ≈ q_ref(τ + δ)``. The coarse δ maximises the cross-
correlation of the mean-removed positions summed over joints, on a common uniform grid
(FFT, :func:`scipy.signal.correlate`), refined to a fraction of a sample by a parabola through
the peak; :func:`sensorless.identification.drive_gains.clock_offset` then polishes it by
Gauss–Newton. The match is scored by the normalised correlation over the overlap,

    r = Σ q̃_load q̃_ref / √(Σ q̃_load² Σ q̃_ref²),

and a pair with ``r < MIN_CORRELATION`` or an overlap under ``MIN_OVERLAP`` of the shorter
log is refused: the two logs are not one trajectory, and no lag makes them one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from .trajectory import Trajectory

__all__ = ["Lag", "MIN_CORRELATION", "MIN_OVERLAP", "estimate_lag"]

MIN_CORRELATION = 0.9
MIN_OVERLAP = 0.5


@dataclass(frozen=True)
class Lag:
    """δ [s] with ``q_load(τ) ≈ q_ref(τ + δ)`` (τ from each log's first sample), its score and overlap."""

    seconds: float
    correlation: float
    overlap_seconds: float

    def to_dict(self) -> dict:
        return {"lag_s": self.seconds, "correlation": self.correlation, "overlap_s": self.overlap_seconds}


def _grid(traj: Trajectory, dt: float) -> np.ndarray:
    t = traj.t - traj.t[0]
    g = np.arange(0.0, t[-1] + 0.5 * dt, dt)
    return np.column_stack([np.interp(g, t, traj.q[:, k]) for k in range(traj.q.shape[1])])


def estimate_lag(load: Trajectory, ref: Trajectory, *, min_correlation: float = MIN_CORRELATION) -> Lag:
    """The lag of ``load`` behind ``ref`` (module docstring); DataError naming both logs when they do not match."""
    from scipy.signal import correlate

    if load.q.shape[1] != ref.q.shape[1] or len(load) < 4 or len(ref) < 4:
        raise DataError(f"cannot pair it with {ref.source}: different joints or fewer than 4 samples", load.source)
    dt = float(min(np.median(np.diff(load.t)), np.median(np.diff(ref.t))))
    a, b = _grid(load, dt), _grid(ref, dt)
    mean = np.concatenate([a, b]).mean(axis=0)
    a, b = a - mean, b - mean
    c = sum(correlate(b[:, k], a[:, k], mode="full", method="fft") for k in range(a.shape[1]))
    lags = np.arange(-(len(a) - 1), len(b))  # c[i]: Σ_n b[n + lag] a[n]
    shorter = min(len(a), len(b))
    overlap = np.minimum(len(a), len(b) - lags) - np.maximum(0, -lags)
    c = np.where(overlap >= MIN_OVERLAP * shorter, c, -np.inf)
    i = int(np.argmax(c))
    if not np.isfinite(c[i]):
        raise DataError(f"does not overlap {ref.source} by half of the shorter log at any lag", load.source)
    k = int(lags[i])
    sa = a[max(0, -k): max(0, -k) + overlap[i]]
    sb = b[max(0, k): max(0, k) + overlap[i]]
    r = float(np.sum(sa * sb) / np.sqrt(max(np.sum(sa**2) * np.sum(sb**2), 1e-300)))
    frac = 0.0
    if 0 < i < len(c) - 1 and np.isfinite(c[i - 1]) and np.isfinite(c[i + 1]):
        den = c[i - 1] - 2 * c[i] + c[i + 1]
        frac = float(0.5 * (c[i - 1] - c[i + 1]) / den) if den < 0 else 0.0
    lag = Lag(seconds=(k + frac) * dt, correlation=r, overlap_seconds=float(overlap[i] * dt))
    if r < min_correlation:
        raise DataError(f"does not look like the same trajectory as {ref.source}: the best match (lag "
                        f"{lag.seconds:.3g} s) correlates only r = {r:.2f} (< {min_correlation}); pair logs of "
                        "one commanded motion", load.source)
    return lag

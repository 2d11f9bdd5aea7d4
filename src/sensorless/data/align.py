"""The time lag between two runs of one trajectory, from their joint positions.

Two logs of the same commanded motion recorded at different times start their excitation at
different instants (seconds apart when an operator starts each run by hand). Measured from
each log's first sample, ``q_load(τ) ≈ q_ref(τ + δ)``. The coarse δ maximises the cross-
correlation of the mean-removed positions summed over joints, on a common uniform grid
(FFT, :func:`scipy.signal.correlate`), refined to a fraction of a sample by a parabola through
the peak; :func:`clock_offset` then polishes it by Gauss–Newton (:func:`pair_lag`). The match
is scored by the normalised correlation over the overlap,

    r = Σ q̃_load q̃_ref / √(Σ q̃_load² Σ q̃_ref²),

and a pair with ``r < MIN_CORRELATION`` or an overlap under ``MIN_OVERLAP`` of the shorter
log is refused: the two logs are not one trajectory, and no lag makes them one.

:func:`pair_logs` turns the pair into row-aligned logs (``align``, :data:`ALIGNMENTS`):
``"time"`` interpolates the reference at the load log's times shifted by the lag, both cut
to their overlap; ``"rows"`` pairs samples by index (same row count); ``"auto"`` (default)
measures the lag and pairs by time, by rows only when both logs share one time grid and the
lag is under :data:`ROWS_LAG` (5 %) of a sample.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import DataError, setting
from .trajectory import Trajectory

__all__ = ["ALIGNMENTS", "Lag", "MIN_CORRELATION", "MIN_OVERLAP", "Pairing", "align_pair", "clock_offset",
           "estimate_lag", "pair_lag", "pair_logs"]

#: how a log is paired with its reference run (module docstring)
ALIGNMENTS = ("auto", "time", "rows")

MIN_CORRELATION = 0.9
MIN_OVERLAP = 0.5
#: ``align="auto"`` pairs logs on one time grid row by row when the lag is under this many samples
ROWS_LAG = 0.05


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
        raise DataError(f"does not overlap {ref.source} by half of the shorter log at any lag: the two are not "
                        f"runs of one trajectory (or one is mostly idle; trim it: {setting('trim', placeholder='FILE=START:END')})",
                        load.source)
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


def pair_lag(load: Trajectory, ref: Trajectory) -> Lag:
    """The lag of ``load`` behind ``ref``: coarse by cross-correlation of the positions
    (:func:`~sensorless.data.align.estimate_lag`, seconds apart; refuses a pair that is not one
    trajectory), then to the sub-sample by :func:`clock_offset` started there."""
    coarse = estimate_lag(load, ref)
    return replace(coarse, seconds=clock_offset(load, ref, start=coarse.seconds))


def clock_offset(load: Trajectory, ref: Trajectory, iterations: int = 4, start: float = 0.0) -> float:
    """δ [s] such that ``ref`` at (t − t₀_ref) = (t − t₀_load) + δ is where ``load`` is: two
    runs of one trajectory started from their first samples are off by that sample's jitter
    (a few ms), and d/dt of the robot's own torque × a few ms biases a gain by ~1 %. Gauss–
    Newton on the positions, q_load(t) ≈ q_ref(t + δ): δ += Σ (q_load − q_ref(t + δ)) q̇_ref / Σ q̇_ref²
    over the samples that move, from ``start`` (``start`` when the runs do not move or have no positions)."""
    if load.q is None or ref.q is None or ref.v is None or load.q.shape[1] != ref.q.shape[1]:
        return start
    tl, tr = load.t - load.t[0], ref.t - ref.t[0]
    dt = float(np.median(np.diff(tr)))
    delta = start
    for _ in range(iterations):
        t = tl + delta
        ok = (t >= tr[0]) & (t <= tr[-1])
        if ok.sum() < 10:
            return start
        qr = np.column_stack([np.interp(t[ok], tr, ref.q[:, k]) for k in range(ref.q.shape[1])])
        vr = np.column_stack([np.interp(t[ok], tr, ref.v[:, k]) for k in range(ref.v.shape[1])])
        den = float(np.sum(vr**2))
        if den <= 0:
            return start
        step = float(np.sum((load.q[ok] - qr) * vr) / den)
        delta += float(np.clip(step, -5 * dt, 5 * dt))
        if abs(step) < 1e-7:
            break
    return delta if abs(delta - start) <= 10 * dt else start


def align_pair(load: Trajectory, ref: Trajectory, lag: Lag | None = None) -> tuple[Trajectory, Trajectory]:
    """Two runs of one trajectory as row-aligned logs: ``ref`` linearly interpolated at the
    times of ``load`` shifted by the lag (default :func:`pair_lag`), both cut to the overlap."""
    lag = lag or pair_lag(load, ref)
    tl, tr = load.t - load.t[0] + lag.seconds, ref.t - ref.t[0]
    keep = (tl >= tr[0]) & (tl <= tr[-1])
    if keep.sum() < 2:
        raise DataError(f"does not overlap {ref.source} in time at a lag of {lag.seconds:+.3f} s", load.source)
    load = load.take(np.flatnonzero(keep))
    tl = tl[keep]

    def at(x):
        if x is None or not hasattr(x, "shape") or x.shape[:1] != (len(tr),):
            return x
        flat = np.asarray(x, dtype=float).reshape(len(tr), -1)
        out = np.column_stack([np.interp(tl, tr, flat[:, k]) for k in range(flat.shape[1])])
        return out.reshape((len(tl),) + x.shape[1:])

    fields = {k: at(getattr(ref, k)) for k in ("q", "v", "a", "tau", "base_q", "base_v", "base_a")}
    extras = {k: at(v) for k, v in (ref.extras or {}).items()}
    return load, ref.with_(t=load.t.copy(), extras=extras, **fields)


@dataclass(frozen=True)
class Pairing:
    """How ``load`` was paired with ``ref`` (file names): ``mode`` "time" | "rows", the ``lag``
    measured (None for ``align="rows"``), and the ``samples`` paired."""

    load: str | None
    ref: str | None
    mode: str
    lag: Lag | None
    samples: int

    def to_dict(self) -> dict:
        return {"log": self.load, "reference": self.ref, "align": self.mode, "samples": self.samples,
                **(self.lag.to_dict() if self.lag is not None else {"lag_s": None})}


def _same_grid(a: Trajectory, b: Trajectory) -> bool:
    if len(a) != len(b):
        return False
    dt = float(np.median(np.diff(a.t)))
    return bool(np.allclose(a.t - a.t[0], b.t - b.t[0], rtol=0.0, atol=1e-3 * dt))


def pair_logs(load: Trajectory, ref: Trajectory, align: str = "auto") -> tuple[Trajectory, Trajectory, Pairing]:
    """``load`` and ``ref`` as row-aligned logs (module docstring), and how they were paired.

    DataError naming both logs when they are not one trajectory, do not overlap, or (rows)
    differ in length."""
    if align not in ALIGNMENTS:
        raise DataError(f"align must be one of {ALIGNMENTS}, got {align!r}")
    if align == "rows":
        if len(load) != len(ref):
            raise DataError(f"has {len(load)} samples but {ref.source} has {len(ref)}: pairing row by row "
                            f"({setting('align', 'rows')}) needs the same rows; trim them to the same rows, or pair by "
                            f"time ({setting('align', 'auto')})",
                            load.source)
        return load, ref, Pairing(load.source, ref.source, "rows", None, len(load))
    lag = pair_lag(load, ref)
    dt = float(np.median(np.diff(load.t)))
    if align == "auto" and _same_grid(load, ref) and abs(lag.seconds) < ROWS_LAG * dt:
        return load, ref, Pairing(load.source, ref.source, "rows", lag, len(load))
    a, b = align_pair(load, ref, lag)
    return a, b, Pairing(load.source, ref.source, "time", lag, len(a))

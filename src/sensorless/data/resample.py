"""Timing of a log (jitter, duplicates, gaps) and resampling onto a uniform grid.

With Δt_k = t_{k+1} − t_k and the nominal period T = median(Δt_k > 0):

* jitter        = std(Δt) / T (reported),
* max_deviation = max |Δt − T| / T (decides: a log is *uniform* when it is ≤ the
  tolerance, 5 % by default, the limit the filters accept),
* a gap is a step Δt > ``max_gap`` · T; interpolating across it would invent data,
  so :func:`resample` refuses it and names the samples around it.

:func:`resample` merges duplicate stamps (their samples are averaged), then
interpolates every per-sample signal onto ``t_0 + k / rate``: cubic splines for the
smooth kinematic signals (q, v, v̇, base pose and twist), linear for torques, currents
and other measured signals (no overshoot at friction reversals), previous-sample for
boolean flags (contacts). Interpolation is :func:`scipy.interpolate.make_interp_spline`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import DataError, TimestampError, setting
from .filtering import MAX_JITTER, MAX_UPSAMPLE, with_arrays, sign_continuous
from .trajectory import Trajectory
from ..errors import TooFewSamplesError

__all__ = ["ARRIVAL_GAP", "ARRIVAL_SHORT_SHARE", "arrival_stamps", "Timing", "timing", "resample", "DEFAULT_MAX_GAP", "CUBIC_FIELDS"]

#: Largest step accepted by :func:`resample`, in nominal periods.
DEFAULT_MAX_GAP = 4.0
#: Signals interpolated with cubic splines (the rest: linear, booleans: previous sample).
CUBIC_FIELDS = ("q", "v", "a", "base_v", "base_a")
_PER_SAMPLE = ("q", "v", "a", "tau", "base_q", "base_v", "base_a")


@dataclass(frozen=True)
class Timing:
    """Sampling statistics of a time column (module docstring)."""

    n_samples: int
    period: float
    rate: float
    jitter: float
    max_deviation: float
    duplicates: int
    backwards: int
    largest_step: float
    largest_step_at: int

    def is_uniform(self, tolerance: float = MAX_JITTER) -> bool:
        """No duplicate or backward stamp, and every step within ``tolerance`` · T of T."""
        return self.duplicates == 0 and self.backwards == 0 and self.max_deviation <= tolerance

    def to_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        return (f"{self.n_samples} samples at {self.rate:.4g} Hz (median period {1e3 * self.period:.3f} ms), "
                f"jitter std {100 * self.jitter:.1f} %, max deviation {100 * self.max_deviation:.0f} %, "
                f"{self.duplicates} duplicate stamp(s), largest step {1e3 * self.largest_step:.3f} ms "
                f"at sample {self.largest_step_at}")


def timing(t: np.ndarray, source: str | None = None) -> Timing:
    """:class:`Timing` of a time column ``t`` [s]."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise TooFewSamplesError(f"timing needs at least 2 time stamps, got shape {t.shape}", source)
    dt = np.diff(t)
    pos = dt[dt > 0]
    if pos.size == 0:
        raise TimestampError("time never increases (all stamps equal or decreasing)", source)
    T = float(np.median(pos))
    k = int(np.argmax(dt))
    return Timing(
        n_samples=int(t.size), period=T, rate=1.0 / T,
        jitter=float(np.std(dt) / T), max_deviation=float(np.max(np.abs(dt - T)) / T),
        duplicates=int(np.sum(dt == 0)), backwards=int(np.sum(dt < 0)),
        largest_step=float(dt[k]), largest_step_at=k + 1,
    )


def _per_sample(traj: Trajectory) -> dict[str, np.ndarray]:
    out = {n: getattr(traj, n) for n in _PER_SAMPLE if getattr(traj, n) is not None}
    for k, v in traj.extras.items():
        v = np.asarray(v)
        if v.ndim >= 1 and v.shape[0] == len(traj) and (np.issubdtype(v.dtype, np.number) or v.dtype == bool):
            out[f"extras.{k}"] = v
    return out


def _merge_duplicates(t: np.ndarray, arrays: dict[str, np.ndarray]) -> tuple[np.ndarray, dict, np.ndarray]:
    """Unique stamps, arrays averaged over each run of equal stamps (booleans: first), and
    the index of each unique stamp's first sample in the input."""
    tu, first, inverse, counts = np.unique(t, return_index=True, return_inverse=True, return_counts=True)
    if tu.size == t.size:
        return t, arrays, np.arange(t.size)
    out = {}
    for name, val in arrays.items():
        if val.dtype == bool or not np.issubdtype(val.dtype, np.floating):
            out[name] = val[first]
            continue
        acc = np.zeros((tu.size,) + val.shape[1:])
        np.add.at(acc, inverse, val)
        out[name] = acc / counts.reshape((-1,) + (1,) * (val.ndim - 1))
    return tu, out, first


def resample(
    traj: Trajectory,
    rate_hz: float | None = None,
    *,
    max_gap: float = DEFAULT_MAX_GAP,
) -> Trajectory:
    """``traj`` on the uniform grid ``t_0 + k / rate_hz`` (default rate: 1 / median period).

    Duplicate stamps are merged (averaged). Raises :class:`~sensorless.errors.TimestampError`
    if time goes backwards or a step exceeds ``max_gap`` nominal periods (naming the
    samples and times around it).
    """
    src = traj.source
    t = np.asarray(traj.t, dtype=float)
    info = timing(t, src)
    if info.backwards:
        i = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
        raise TimestampError(
            f"time goes backwards at sample {i}: t[{i}]={t[i]:.6f} s after t[{i - 1}]={t[i - 1]:.6f} s "
            f"({info.backwards} backward step(s)); resampling cannot order it — fix or split the log", src)
    if not (np.isfinite(max_gap) and max_gap > 1):
        raise DataError(f"resample: max_gap must be a number of periods > 1, got {max_gap!r}", src)
    rate = info.rate if rate_hz is None else float(rate_hz)
    if not (np.isfinite(rate) and rate > 0):
        raise DataError(f"resample: rate must be a positive number of Hz, got {rate_hz!r}", src)
    tu, arrays, first = _merge_duplicates(t, _per_sample(traj))
    steps = np.diff(tu)
    limit = max_gap * info.period
    big = np.flatnonzero(steps > limit)
    if big.size:
        k = int(big[0])
        a, b = int(first[k]), int(first[k + 1])
        arrival = arrival_stamps(t)
        fix = (f"; the stamps look like arrival times ({arrival}): read the samples as uniform at their mean rate "
               f"with {setting('time_from', 'rate')}" if arrival else
               f"; trim the log around it ({setting('trim')}) or raise the tolerance ({setting('max_gap')})")
        raise TimestampError(
            f"gap of {1e3 * steps[k]:.1f} ms between sample {a} (t={tu[k]:.6f} s) and sample {b} "
            f"(t={tu[k + 1]:.6f} s), more than {max_gap:g} × the median period "
            f"({1e3 * info.period:.3f} ms; {big.size} such gap(s)){fix}", src)
    if tu.size < 2:
        raise TooFewSamplesError("resample: fewer than 2 distinct time stamps", src)
    from scipy.interpolate import interp1d, make_interp_spline  # imported on use (start-up time)

    rel = tu - tu[0]
    n_given = len(traj.t)
    if rel[-1] * rate + 1 > MAX_UPSAMPLE * max(n_given, 1):  # 1e12 Hz would allocate TiB
        raise DataError(f"resampling at {rate:g} Hz would make {rel[-1] * rate + 1:.3g} samples of the log's "
                        f"{n_given} (more than {MAX_UPSAMPLE}×); choose a rate near the log's own", src)
    n = int(np.floor(rel[-1] * rate + 1e-9)) + 1
    grid = np.arange(n) / rate
    out: dict[str, np.ndarray] = {}
    for name, val in arrays.items():
        field = name.removeprefix("extras.")
        if val.dtype == bool or not np.issubdtype(val.dtype, np.floating):  # flags, counters: previous sample
            idx = np.clip(np.searchsorted(rel, grid, side="right") - 1, 0, rel.size - 1)
            out[name] = val[idx]
            continue
        val = np.asarray(val, dtype=float)
        k = 3 if field in CUBIC_FIELDS and rel.size >= 4 else 1
        if name == "base_q":  # position cubic, quaternion (sign-continuous: q ≡ −q) linear then renormalised
            pos = make_interp_spline(rel, val[:, :3], k=3 if rel.size >= 4 else 1, axis=0)(grid)
            quat = interp1d(rel, sign_continuous(val[:, 3:]), axis=0, assume_sorted=True)(grid)
            out[name] = np.hstack([pos, quat / np.linalg.norm(quat, axis=1, keepdims=True)])
        else:
            out[name] = make_interp_spline(rel, val, k=k, axis=0)(grid)
    note = (f"resample({rate:g} Hz uniform; cubic {[f for f in CUBIC_FIELDS if f in out]}, linear others; "
            f"{info.duplicates} duplicate stamp(s) merged)")
    units = dict(traj.units)
    units["processing"] = f"{units['processing']}; {note}" if units.get("processing") else note
    prov = {**traj.provenance, "resampled": {"rate_hz": rate, "max_gap_periods": max_gap,
                                             "duplicates_merged": info.duplicates, "before": info.to_dict()}}
    return with_arrays(traj, out, t=tu[0] + grid, units=units, provenance=prov)


#: arrival-time stamps: at least this share of the steps under a tenth of the mean step, and gaps over
#: :data:`ARRIVAL_GAP` mean steps (samples delivered in bursts: 0.3 ms apart after 40–170 ms)
ARRIVAL_SHORT_SHARE = 0.3
ARRIVAL_GAP = 3.0


def arrival_stamps(t: np.ndarray) -> str:
    """A description of the burst pattern when the stamps ``t`` are arrival times (samples delivered in packets:
    many steps far below the mean and gaps far above it), else ``""``."""
    t = np.asarray(t, dtype=float)
    steps = np.diff(t)
    if steps.size < 10 or not np.all(np.isfinite(steps)):
        return ""
    mean = (t[-1] - t[0]) / steps.size
    short, gaps = steps < 0.1 * mean, steps > ARRIVAL_GAP * mean
    if mean <= 0 or short.mean() < ARRIVAL_SHORT_SHARE or not gaps.any():
        return ""
    return (f"{100 * short.mean():.0f} % of the steps under {1e3 * 0.1 * mean:.3g} ms, bursts after gaps of up to "
            f"{1e3 * steps.max():.3g} ms; mean rate {1 / mean:.6g} Hz")

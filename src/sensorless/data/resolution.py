"""The resolution of a logged signal, read from the log itself: its quantization step and its rounding.

A real channel is quantized twice over: the encoder counts in steps (1e-4 rad, a height sensor's
0.25 mm) and the logger writes a fixed number of decimals (a UR writes q and v to 4). Both set a
floor under the signal's noise that its sample-to-sample scatter does not show: a joint held still
logs one value for seconds, so the scatter (a MAD) is 0, or 1e-26 from rounding in the smoother.

* **decimals** d: the fewest decimals (0–9) that write every sample exactly, |x·10ᵈ − round(x·10ᵈ)| ≤
  :data:`DECIMAL_TOLERANCE` (in units of the last decimal; loose enough for a float32 file, tight
  enough that a continuous signal never passes: each sample passes by chance with probability
  2·tolerance, and a signal smaller than one unit of the last decimal does not count as written
  with that many; the tolerance grows to a float32 file's precision, and a signal that needs more
  decimals than that carries is not rounded). A column with fewer than 2 distinct values tells nothing (None).
* **step** Δ: the gcd-like smallest common increment of the sample differences: the smallest
  non-zero |Δx| (or a divisor of it by 2…:data:`MAX_DIVISOR`) that all but :data:`STEP_MISFIT_SHARE`
  of the non-zero differences are integer multiples of (to 5 % of Δ). A signal with decimals d has
  Δ ≥ 10⁻ᵈ; a continuous one has none (0).

The noise floor of a quantized signal is that of a uniform error over one step, Δ/√12
(:func:`noise_floor`); :func:`~sensorless.data.rest.signal_noise` never reports less.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DECIMAL_TOLERANCE", "MAX_DIVISOR", "STEP_MISFIT_SHARE", "Resolution", "channel_resolution",
           "noise_floor", "record_floor", "resolution_record"]

DECIMAL_TOLERANCE = 1e-3
MAX_DIVISOR = 10
STEP_MISFIT_SHARE = 0.01
#: at most this many samples (the first ones: a log does not change its resolution) enter the search
MAX_SAMPLES = 200_000


@dataclass(frozen=True)
class Resolution:
    """One channel's quantization ``step`` (0: none detected) and ``decimals`` (None: not rounded)."""

    step: float = 0.0
    decimals: "int | None" = None

    @property
    def floor(self) -> float:
        """The noise std of the quantization alone, Δ/√12."""
        return self.step / np.sqrt(12.0)

    def to_dict(self) -> dict:
        return {"step": float(self.step), "decimals": self.decimals}


def _decimals(x: np.ndarray) -> "int | None":
    if np.ptp(x) == 0:
        return None
    for d in range(0, 10):
        s = x * 10.0**d
        tol = DECIMAL_TOLERANCE + 2e-7 * np.max(np.abs(s))  # a float32 file's precision
        if tol > 50 * DECIMAL_TOLERANCE:  # more decimals than the numbers carry: not rounded
            return None
        r = np.round(s)
        if np.ptp(r) > 0 and np.max(np.abs(s - r)) <= tol:  # exact, and the rounded values still differ
            return d
    return None


def _step(x: np.ndarray, least: float) -> float:
    d = np.abs(np.diff(x))
    scale = max(float(np.max(np.abs(x))), 1e-300)
    nz = d[d > max(1e-12 * scale, 0.5 * least)]
    if nz.size < 3:
        return least
    s0 = float(np.min(nz))
    for k in range(1, MAX_DIVISOR + 1):
        s = s0 / k
        if s < 0.5 * least:
            break
        misfit = np.abs(nz - s * np.round(nz / s)) > 0.05 * s
        if np.mean(misfit) <= STEP_MISFIT_SHARE:
            return s
    return least


def channel_resolution(x) -> Resolution:
    """The :class:`Resolution` of one channel (module docstring); NaNs are ignored."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)][:MAX_SAMPLES + 1]
    if x.size < 2:
        return Resolution()
    dec = _decimals(x)
    least = 10.0**-dec if dec is not None else 0.0
    return Resolution(step=_step(x, least), decimals=dec)


def noise_floor(x) -> np.ndarray:
    """Per column of ``x`` (N, n) (or one column): Δ/√12, the noise std its quantization alone implies."""
    x = np.asarray(x, dtype=float)
    cols = x[:, None] if x.ndim == 1 else x
    return np.array([channel_resolution(c).floor for c in cols.T])


def resolution_record(traj, fields=("q", "v", "tau")) -> dict:
    """``{field: {joint: {"step", "decimals"}}}`` for the channels of ``traj`` that are quantized or rounded
    (the ``provenance["resolution"]`` record, written to result.json with the log's signals)."""
    out = {}
    for f in fields:
        x = getattr(traj, f, None)
        if x is None:
            continue
        x = np.asarray(x, dtype=float)
        names = traj.joint_names if x.shape[1] == len(traj.joint_names) else [str(i) for i in range(x.shape[1])]
        rec = {n: channel_resolution(x[:, j]).to_dict() for j, n in enumerate(names)}
        rec = {n: r for n, r in rec.items() if r["step"] > 0 or r["decimals"] is not None}
        if rec:
            out[f] = rec
    return out


def record_floor(record: dict, field: str, names) -> np.ndarray:
    """Δ/√12 per joint of ``names`` from a :func:`resolution_record` (0 where the channel is not quantized)."""
    rec = (record or {}).get(field, {})
    return np.array([float(rec.get(n, {}).get("step", 0.0)) for n in names]) / np.sqrt(12.0)

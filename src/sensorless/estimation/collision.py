"""Collision (contact) detection on the observer's external-torque estimate.

Per joint j, from a quiet segment (no contact) of the observer output r:

    b_j = median(r_j),  σ_j = std(r_j),  contact  ⇔  ∃ j: |r_j − b_j| > k σ_j.

``k`` is given, or chosen for a false-alarm rate λ [1/min] under a Gaussian model of the
quiet residual: each of the n joints may exceed at a per-sample probability
p = λ·dt / (60 n), so k = Φ⁻¹(1 − p/2). (The observer output is low-pass, so exceedances
come in bursts and the realised rate of *intervals* is below λ; measure it with
:func:`score_detection`.) Contact intervals are the runs of the flag, merged across gaps
shorter than ``merge_gap`` and kept when at least ``min_duration`` long.

The quiet segment is a time window with the syntax of ``--trim``
(:class:`~sensorless.data.prepare.TrimWindow`: seconds after the first sample, ``abs:``
for the log's own stamps). The observer's filters start from zero state, so its output
is a start-up transient until L(s) has converged: :func:`observer_warmup` is the time its
step response needs to stay within ``tol`` of 1 (order 1: ln(1/tol)/K ≈ 6.9/K; order 2,
ζ = 1: ≈ 9.2/K for tol = 10⁻³); those samples are never flagged and never quiet.

The quiet segment is checked before it is used (:func:`check_quiet_window`): a push inside it
would set σ to the push (10 N·m instead of 0.01) and hide every later contact. Its spread per joint
is compared with the typical spread of the log, the median standard deviation of all windows of the
same length after the warm-up (most of a log is contact-free); more than :data:`QUIET_SPREAD_RATIO`
times it is refused, naming the joint and the quietest window of the log.
A robot held still needs more than one threshold per joint: see :mod:`.static_band`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import stats

from ..data.integral_filter import observer_filter
from ..data.trims import TrimWindow
from ..errors import DataError, setting

__all__ = ["ContactInterval", "QUIET_SPREAD_RATIO", "Thresholds", "check_quiet_window", "contact_intervals",
           "detect_contacts", "observer_warmup", "quiet_mask", "threshold_multiplier",
           "quiet_thresholds", "runs", "score_detection"]


@dataclass
class Thresholds:
    names: list[str]
    bias: np.ndarray
    sigma: np.ndarray
    k: float
    samples: int

    @property
    def threshold(self) -> np.ndarray:
        return self.k * self.sigma

    def to_dict(self) -> dict:
        return {"names": list(self.names), "bias": self.bias.tolist(), "sigma": self.sigma.tolist(), "k": self.k,
                "threshold": self.threshold.tolist(), "quiet_samples": self.samples}


@dataclass
class ContactInterval:
    start: float
    end: float
    start_index: int
    end_index: int  # inclusive
    peak: list[float]  # signed peak of r − b per joint over the interval
    peak_time: list[float]
    joints: list[str]  # joints whose threshold was crossed
    #: per crossed joint, "moving" or "rest" (the state at its peak); empty from :func:`detect_contacts`
    state: dict = field(default_factory=dict)
    #: per crossed joint at rest: how far r left the static-friction band, a lower bound of |τ_ext| [N·m]
    band_excess: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return asdict(self)


def quiet_mask(t: np.ndarray, window: "str | tuple | TrimWindow", source: str = "<log>",
               exclude: "np.ndarray | None" = None) -> np.ndarray:
    """Samples inside ``window`` (``--trim`` syntax: seconds after the first sample, negative
    from the end, ``abs:`` stamps), minus ``exclude`` (e.g. the observer warm-up); DataError
    if fewer than 20 remain."""
    t = np.asarray(t, float)
    try:
        win = TrimWindow.parse(window)
    except DataError as e:
        raise DataError(f"{setting('quiet')}: {e.args[0]}", source) from None
    lo, hi = win.bounds(t)
    inside = (t >= lo) & (t <= hi)
    mask = inside & (True if exclude is None else ~np.asarray(exclude, bool))
    if mask.sum() < 20:
        rel = f" = {lo - t[0]:.6g}..{hi - t[0]:.6g} s after the first sample" if win.absolute else ""
        left = f", {int(mask.sum())} after the observer warm-up" if exclude is not None and inside.sum() >= 20 else ""
        spec = window.strip() if isinstance(window, str) else str(win)  # str(win) rounds stamps
        raise DataError(f"quiet segment {spec}{rel} holds {int(inside.sum())} samples{left} (need ≥ 20; the log spans "
                        f"{t[-1] - t[0]:.3f} s, stamps {t[0]:.6f} to {t[-1]:.6f})", source)
    return mask


#: a quiet window whose spread exceeds this many times the log's typical spread (per joint) holds a contact
QUIET_SPREAD_RATIO = 4.0


def _window_std(x: np.ndarray, w: int) -> np.ndarray:
    """Standard deviation of every window of ``w`` samples of the columns of ``x`` (N, n) → (N − w + 1, n)."""
    c1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    c2 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x * x, axis=0)])
    m = (c1[w:] - c1[:-w]) / w
    return np.sqrt(np.maximum((c2[w:] - c2[:-w]) / w - m * m, 0.0))


def check_quiet_window(r: np.ndarray, t: np.ndarray, quiet: np.ndarray, names, window: str,
                       usable: "np.ndarray | None" = None, source: str = "<log>") -> None:
    """DataError when the quiet window of the observer output ``r`` (N, n) holds a contact (module docstring);
    ``usable`` (N,) marks the samples windows may cover (default all, e.g. after the warm-up)."""
    r, t, quiet = np.asarray(r, float), np.asarray(t, float), np.asarray(quiet, bool)
    usable = np.ones(len(t), bool) if usable is None else np.asarray(usable, bool)
    idx = np.flatnonzero(quiet)
    w = int(idx[-1] - idx[0] + 1)
    start = int(np.argmax(usable))
    x = r[start:]
    if len(x) < 3 * w or not np.all(np.isfinite(x)):
        return  # too short a log to compare the window with
    spread = _window_std(x, w)
    typical = np.median(spread, axis=0)
    mine = r[quiet].std(axis=0)
    ratio = mine / np.where(typical > 0, typical, np.inf)
    bad = np.flatnonzero(ratio > QUIET_SPREAD_RATIO)
    if not bad.size:
        return
    j = int(bad[np.argmax(ratio[bad])])
    best = start + int(np.argmin(np.max(spread / np.where(typical > 0, typical, 1.0), axis=1)))
    lo, hi = t[best] - t[0], t[min(best + w - 1, len(t) - 1)] - t[0]
    raise DataError(f"{setting('quiet', window)}: the quiet window is not contact-free: on {names[j]} the observer "
                    f"output spreads {mine[j]:.3g} N·m there, {ratio[j]:.0f}× its typical {typical[j]:.3g} N·m over "
                    f"windows of the same length (a push or a motion inside it would set every threshold); the quietest "
                    f"window of the log is {setting('quiet', f'{lo:.3f}:{hi:.3f}')}", source)


def observer_warmup(gain: float, order: int, dt: float, damping: float = 1.0, tol: float = 1e-3) -> float:
    """Seconds until the observer's L(s) (Tustin, zero initial state) has converged: the last
    time its step response is more than ``tol`` away from 1."""
    _, b, a = observer_filter(gain, order, dt, damping)
    n = int(np.ceil(50.0 / (gain * dt))) + 10  # ≫ the slowest time constant
    from scipy import signal

    step = signal.lfilter(b, a, np.ones(n))
    off = np.flatnonzero(np.abs(step - 1.0) > tol)
    return float((off[-1] + 1) * dt) if off.size else 0.0


def threshold_multiplier(k: float | None, false_alarm_rate: float | None, dt: float | None, n: int) -> float:
    """k given, or from a false-alarm rate λ [1/min] over ``n`` joints (Gaussian, two-sided): per-sample
    p = λ dt / (60 n), k = Φ⁻¹(1 − p/2). Exactly one of ``k`` and ``false_alarm_rate``."""
    if (k is None) == (false_alarm_rate is None):
        raise DataError("give exactly one of k or false_alarm_rate")
    if false_alarm_rate is not None:
        if not (false_alarm_rate > 0 and dt and dt > 0):
            raise DataError(f"false_alarm_rate must be > 0 per minute with a sample period dt, got {false_alarm_rate}, dt={dt}")
        k = float(stats.norm.isf(false_alarm_rate * dt / (60.0 * n) / 2))
    if not k > 0:
        raise DataError(f"k must be > 0, got {k}")
    return float(k)


def quiet_thresholds(r: np.ndarray, quiet: np.ndarray, names, *, k: float | None = None,
                     false_alarm_rate: float | None = None, dt: float | None = None) -> Thresholds:
    """Per-joint bias and σ from the quiet samples (boolean mask) and the multiplier k."""
    r = np.asarray(r, float)
    rq = r[np.asarray(quiet, bool)]
    if rq.shape[0] < 20:
        raise DataError(f"the quiet segment has {rq.shape[0]} samples; need ≥ 20")
    k = threshold_multiplier(k, false_alarm_rate, dt, r.shape[1])
    bias = np.median(rq, axis=0)
    sigma = np.maximum(rq.std(axis=0), 1e-12)
    return Thresholds(list(names), bias, sigma, float(k), int(rq.shape[0]))


def detect_contacts(r: np.ndarray, t: np.ndarray, th: Thresholds, *, min_duration: float = 0.0,
                    merge_gap: float = 0.0) -> tuple[np.ndarray, list[ContactInterval]]:
    """(flag (N,), intervals) of samples where some joint's |r − b| exceeds k σ."""
    r, t = np.asarray(r, float), np.asarray(t, float)
    dev = r - th.bias
    over = np.abs(dev) > th.threshold
    return contact_intervals(over, t, dev, th.names, min_duration=min_duration, merge_gap=merge_gap)


def contact_intervals(over: np.ndarray, t: np.ndarray, dev: np.ndarray, names, *, min_duration: float = 0.0,
                      merge_gap: float = 0.0) -> tuple[np.ndarray, list[ContactInterval]]:
    """(flag (N,), intervals) from per-joint crossings ``over`` (N, n): runs of any crossing,
    merged across gaps ≤ ``merge_gap``, kept when ≥ ``min_duration``; peaks of ``dev`` (N, n)."""
    over = np.asarray(over, bool)
    flag = over.any(axis=1)
    merged: list[list[int]] = []
    for s, e in runs(flag):
        if merged and t[s] - t[merged[-1][1]] <= merge_gap:
            merged[-1][1] = e
        else:
            merged.append([s, e])
    out, flag = [], np.zeros_like(flag)
    for s, e in merged:
        if t[e] - t[s] < min_duration:
            continue
        seg = dev[s : e + 1]
        i = np.argmax(np.abs(np.nan_to_num(seg)), axis=0)
        out.append(ContactInterval(
            float(t[s]), float(t[e]), int(s), int(e), seg[i, np.arange(seg.shape[1])].tolist(),
            t[s + i].tolist(), [n for n, o in zip(names, over[s : e + 1].any(axis=0)) if o],
        ))
        flag[s : e + 1] = True
    return flag, out


def runs(flag: np.ndarray) -> list[tuple[int, int]]:
    """(start, end inclusive) of the runs of True."""
    d = np.diff(np.concatenate([[0], flag.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def score_detection(intervals: list[ContactInterval], t: np.ndarray, truth: np.ndarray) -> dict:
    """Delay of the first detection after each true contact onset, and false alarms.

    ``truth`` (N,) bool marks the true contact samples. An interval overlapping no true
    contact (± 0.2 s) is a false alarm; rates are per minute of contact-free time.
    """
    t, truth = np.asarray(t, float), np.asarray(truth, bool)
    onsets = [(t[s], t[e]) for s, e in runs(truth)]
    delays, missed = [], 0
    for a, b in onsets:
        hits = [iv.start for iv in intervals if iv.end >= a and iv.start <= b]
        if hits:
            delays.append(max(0.0, min(hits) - a))
        else:
            missed += 1
    false = [iv for iv in intervals if not any(iv.end >= a - 0.2 and iv.start <= b + 0.2 for a, b in onsets)]
    dt = float(np.median(np.diff(t)))
    quiet_minutes = (~truth).sum() * dt / 60.0
    return {
        "contacts": len(onsets),
        "detected": len(onsets) - missed,
        "missed": missed,
        "delays_s": delays,
        "mean_delay_s": float(np.mean(delays)) if delays else float("nan"),
        "false_alarms": len(false),
        "false_alarms_per_minute": len(false) / quiet_minutes if quiet_minutes > 0 else float("nan"),
    }

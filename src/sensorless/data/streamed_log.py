"""A long log preprocessed chunk by chunk, with the same samples as the whole-log :func:`~.prepare.prepare`.

The default preprocessing of a log with t, q, v, τ (uniform time, no trim, low-pass or decimation)
is: v̇ = the Savitzky–Golay derivative of the logged v (window w, order 3, ``mode="interp"`` at the
log's ends), then rest detection (:mod:`.rest`) with the noise σ_v, σ_q of the whole log. Two
things depend on the whole log, and are measured first by :func:`scan_log`, one joint at a time
(one column of N floats in memory, never the log):

* robust statistics: medians and percentiles (the outlier test of :mod:`.outliers`, σ_v, σ_q and
  σ_τ of :func:`~.rest.signal_noise`, the P95 |v| speed scale of the friction grids) and the
  excitation period (autocorrelation of q by FFT, :func:`~.periodicity.excitation_period`,
  accumulated over joints in the same order);
* rest: the quiet mask and the creeping drift of each joint (:func:`~.rest.rest_state`, as :func:`~.rest.zero_at_rest` has it, on that
  joint's column), kept as a bool mask and the few creeping samples.

:meth:`StreamedLog.chunks` then yields the preprocessed log in chunks: each chunk's v̇ is the
derivative of the chunk read with w // 2 samples of overlap on each side, so every output sees
the same window of samples as in the whole log (the convolution is the same per sample; the ends
of the log use the same edge fit), and rest is applied from the masks.

Validation names the sample in the whole log: a non-finite value (field, joint, sample, time),
time going backwards. Logs this path does not reproduce exactly (non-uniform or duplicated stamps,
gross outliers, too short) make :func:`scan_log` return None: the whole-log path then handles them
(resampling, or its typed error).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from ..errors import NonFiniteError, TimestampError
from .chunks import ChunkedLog
from .filtering import DEFAULT_SAVGOL_WINDOW, SavitzkyGolay, default_savgol_window
from .outliers import OUTLIER_THRESHOLD, robust_scale
from .rest import rest_info, rest_state, signal_noise
from .trajectory import Trajectory

__all__ = ["POLYORDER", "StreamedLog", "scan_log"]

#: Savitzky–Golay polynomial order of the derivatives (as :func:`~.prepare.prepare`)
POLYORDER = 3
#: samples per read of one column in the scan
_READ = 1 << 16


@dataclass
class StreamedLog:
    """What :func:`scan_log` measured on a log, and its preprocessed chunks (:meth:`chunks`)."""

    log: ChunkedLog
    t: np.ndarray
    window: int
    dt: float
    velocity_noise: np.ndarray  # of the logged v, before rest
    position_noise: "np.ndarray | None"
    torque_noise: np.ndarray
    speed: np.ndarray
    moving: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    period: "float | None"
    quiet: "np.ndarray | None" = None
    creep: list = field(default_factory=list)
    provenance: dict = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return len(self.t)

    @property
    def source(self) -> str:
        return str(self.log.path)

    def chunks(self, size: int) -> Iterator[tuple[int, int, Trajectory]]:
        """(start, n, chunk): samples [start, start + n) preprocessed, plus the next sample when there is
        one (``len(chunk) == n + 1``: the look-ahead a velocity-reversal test needs). The log is read once,
        in order; w // 2 samples on each side of a chunk are kept for its derivative."""
        N, h = self.n_samples, self.window // 2
        sg = SavitzkyGolay(self.window, POLYORDER, self.dt)
        valid = ValidCorrelation(sg.coeffs[1])
        reader = self.log.chunks(["q", "v", "tau"], max(size, h + 2))
        buf, b0 = {"q": np.zeros((0, 0)), "v": None, "tau": None}, 0  # raw samples [b0, b0 + len)
        for s in range(0, N, size):
            e = min(s + size, N)
            hi = min(e + 1, N)  # with the look-ahead sample
            lo_r = max(s - h, 0)
            need = min(max(hi + h, lo_r + self.window), N)  # at least a window: the edge fits at the log's ends
            lo_r = max(min(lo_r, need - self.window), 0)
            while buf["v"] is None or b0 + len(buf["v"]) < need:
                _, raw = next(reader)
                buf = raw if buf["v"] is None else {k: np.concatenate([buf[k], raw[k]]) for k in raw}
            win = {k: x[lo_r - b0 : need - b0] for k, x in buf.items()}
            if lo_r == 0 or need == N:  # a window at the log's ends: its edge fit
                a = sg.apply(win["v"], 1)[s - lo_r : hi - lo_r]
            else:  # inside the log every output is the plain correlation of its window
                a = valid(win["v"])[s - lo_r - h : hi - lo_r - h]
            v = win["v"][s - lo_r : hi - lo_r].copy()
            if self.quiet is not None:
                qm = self.quiet[s:hi]
                a[qm] = 0.0
                v[qm] = 0.0
                for j, (idx, drift) in enumerate(self.creep):
                    k0, k1 = np.searchsorted(idx, [s, hi])
                    v[idx[k0:k1] - s, j] = drift[k0:k1]
            yield s, e - s, Trajectory(t=self.t[s:hi], q=win["q"][s - lo_r : hi - lo_r].copy(), v=v, a=a,
                                       tau=win["tau"][s - lo_r : hi - lo_r].copy(),
                                       joint_names=list(self.log.joint_names), source=self.source)
            keep = max(e - self.window, 0)  # the next chunk starts at e and looks back h (at the end: w) samples
            buf = {k: x[keep - b0 :] for k, x in buf.items()}
            b0 = keep


class ValidCorrelation:
    """y[i] = Σ_k c[k] x[i + k] along axis 0, for the windows that fit in x (len(x) − len(c) + 1 outputs):
    the Savitzky–Golay derivative inside a log (coefficients ``c`` in dot order). By FFT (O(n log n)
    per chunk instead of the window's 201 multiply-adds per sample at 1 kHz: 0.1 instead of 1.2 µs per
    sample on the UR5 benchmark); equal to the direct sum to rounding (relative 1e-13 of the largest
    output, tested)."""

    def __init__(self, c: np.ndarray):
        self.c = np.asarray(c, dtype=float)[::-1].copy()  # correlation = convolution with c reversed
        self._spectra: dict[int, np.ndarray] = {}

    def __call__(self, x: np.ndarray) -> np.ndarray:
        w, n = len(self.c), x.shape[0]
        size = 1 << int(np.ceil(np.log2(n + w - 1)))  # no wrap-around: linear convolution
        C = self._spectra.get(size)
        if C is None:
            C = self._spectra[size] = np.fft.rfft(self.c, size)
        X = np.fft.rfft(x, size, axis=0)
        X *= C.reshape((-1,) + (1,) * (x.ndim - 1))
        return np.fft.irfft(X, size, axis=0)[w - 1 : n]


def _finite(x: np.ndarray, fld: str, joint: str, t: np.ndarray, src: str) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.argmax(bad))
        raise NonFiniteError(f"'{fld}' column '{joint}' has {int(bad.sum())} non-finite values (NaN/inf), first at "
                             f"sample {i} (t={t[i]:.6g} s)", src)


def _outlying(x: np.ndarray) -> bool:
    m, s = robust_scale(x[:, None])
    return bool(np.any(np.abs(x - m[0]) > OUTLIER_THRESHOLD * s[0]))


def scan_log(log: ChunkedLog, *, rest: str = "auto", min_samples: int = 0, period: bool = True) -> "StreamedLog | None":
    """Measure ``log`` for the streamed preprocessing (module docstring), one joint at a time; None
    when the whole-log path must handle it. Raises NonFiniteError / TimestampError naming the sample.
    ``period``: find the excitation period (for cross-validation folds; else ``StreamedLog.period`` is None)."""
    from .resample import timing
    from .filtering import MAX_JITTER
    from .timebase import to_seconds

    src, N = str(log.path), log.n_samples
    if N < max(min_samples, 3 * DEFAULT_SAVGOL_WINDOW + 2, 64):
        return None
    t = log.column("t", size=_READ)
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise NonFiniteError(f"time column 't' has a non-finite value (NaN/inf) at sample {i}", src)
    t, unit = to_seconds(t, None, None, "t", src)
    if unit != "s":
        return None
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise TimestampError(f"time goes backwards at sample {i} (t={t[i - 1]:.6f} -> {t[i]:.6f} s; "
                             f"{back.size} such step(s))", src)
    info = timing(t, src)
    if info.duplicates or not info.is_uniform(MAX_JITTER):
        return None  # resampled by the whole-log path
    dt = float(np.median(np.diff(t)))
    w = default_savgol_window(1.0 / dt if dt > 0 else float("nan"))
    names = list(log.joint_names)
    n = len(names)
    rest_on = rest == "auto" and N > 3 * DEFAULT_SAVGOL_WINDOW
    sv, sq, st = np.zeros(n), np.zeros(n), np.zeros(n)
    speed, moving, qmin, qmax = np.zeros(n), np.zeros(n, bool), np.zeros(n), np.zeros(n)
    quiet = np.zeros((N, n), dtype=bool) if rest_on else None
    creep, frac_rest, frac_creep = [], np.zeros(n), np.zeros(n)
    power, ac_k, lags = None, 0, _lag_range(N, dt) if period else None
    for j, name in enumerate(names):
        cols = {}
        for fld in ("tau", "q", "v"):  # τ is done with before q and v are read (memory)
            x = log.column(fld, j, _READ)
            _finite(x, fld, name, t, src)
            if _outlying(x):
                return None  # the whole-log path raises (or drops, with --outliers) naming the sample
            if fld == "tau":
                st[j] = signal_noise(x[:, None])[0]
            else:
                cols[fld] = x
            del x
        q, v = cols.pop("q"), cols.pop("v")
        sv[j] = signal_noise(v[:, None])[0]
        qmin[j], qmax[j] = q.min(), q.max()
        moving[j] = np.ptp(q) >= 1e-3
        if rest_on:
            sq[j] = signal_noise(q[:, None])[0]
            qj, cj, vj = rest_state(v[:, None], dt, sv[j : j + 1], w, q[:, None], sq[j : j + 1])
            quiet[:, j] = qj[:, 0]
            vj = vj[:, 0]
            idx = np.flatnonzero(quiet[:, j] & (vj != 0.0))
            creep.append((idx, vj[idx].copy()))
            frac_rest[j], frac_creep[j] = (qj & ~cj).mean(), cj.mean()
            v = vj
            del qj, cj
        speed[j] = np.percentile(np.abs(v), 95)
        if lags is not None:
            p = _power(q)
            if p is not None:
                power = p if power is None else np.add(power, p, out=power)
                ac_k += 1
        del q, v
    period = _period(power, ac_k, N, lags, dt)
    prov = {"t": "logged", "q": "logged", "v": "logged", "tau": "logged",
            "a": f"derived: d/dt of logged v, Savitzky-Golay (window {w}, order {POLYORDER})",
            "timing": info.to_dict()}
    if rest_on:
        prov["rest"] = rest_info(names, sv, w, sq, frac_rest, frac_creep)
    return StreamedLog(log, t, w, dt, sv, sq if rest_on else None, st, speed, moving, qmin,
                       qmax, period, quiet, creep, prov)


def _lag_range(n: int, dt: float, min_period: float = 1.0) -> "tuple[int, int] | None":
    if n < 8 or not np.isfinite(dt) or dt <= 0:
        return None
    lo, hi = max(int(np.ceil(min_period / dt)), 1), int(0.6 * n)
    return None if hi <= lo + 1 else (lo, hi)


def _power(q: np.ndarray) -> "np.ndarray | None":
    """One joint's power spectrum |X|² / var of q − q̄ zero-padded to 2n (:func:`~.periodicity.excitation_period`):
    the joints' normalised autocorrelations are summed as spectra, one inverse FFT for all (linear)."""
    n = len(q)
    x = q - q.mean()
    var = (x**2).mean()
    if not var > 0:
        return None
    p = np.abs(np.fft.rfft(x, 2 * n))  # the same operations as excitation_period, in place (memory)
    del x
    p **= 2
    p /= var
    return p


def _period(power, k: int, n: int, lags, dt: float, threshold: float = 0.95) -> "float | None":
    """The mean over the ``k`` joints of their normalised autocorrelations,
    irfft(Σ |X_j|²/var_j)[τ] / (n − τ) / k at lags [lo − 1, hi]: its first peak above ``threshold``
    (:func:`~.periodicity.excitation_period`)."""
    if power is None or lags is None:
        return None
    ac = np.fft.irfft(power)[lags[0] - 1 : lags[1] + 1]
    ac /= n - np.arange(lags[0] - 1, lags[1] + 1)
    r = ac / k
    peak = (r[1:-1] >= r[:-2]) & (r[1:-1] >= r[2:]) & (r[1:-1] >= threshold)
    idx = np.flatnonzero(peak)
    return float((lags[0] + idx[0]) * dt) if idx.size else None

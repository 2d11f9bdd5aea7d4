"""Is the logged joint velocity the derivative of the logged position?

A log whose ``v`` column is not dq/dt (q and v swapped, v in other units, v delayed by a filter or a
transport, or v of another joint) gives a model that explains nothing, with exit 0. :func:`check_velocity`
measures, per moving joint, how the logged v compares with dq/dt differentiated from the logged q: the
correlation at zero lag and at the best lag (within ±:data:`MAX_LAG` s), that lag, and the scale
(least-squares slope of v on dq/dt). Both signals pass through the same zero-phase low-pass, at a
few times the band of the logged motion (:data:`BAND_FACTOR`, :data:`BAND_ENERGY`), so the comparison
has no lag or gain of its own, and the derivative of a noisy, quantized or rounded q does not pass for
a mismatch. A joint that barely moves (range of q under
:data:`MIN_RANGE`) is not judged.

The verdicts (:class:`VelocityCheck`): ``refuse`` when v cannot be dq/dt (a correlation at zero lag
of −:data:`MIN_CORRELATION` or below, a correlated v at a scale outside [1/:data:`MAX_SCALE`,
:data:`MAX_SCALE`], or v matching another joint's dq/dt far better than its own);
``warn`` when the correlation stays under :data:`MIN_CORRELATION` at every lag (evidence a joint
moving in a short part of the log cannot make certain), or when v is dq/dt delayed by more than :data:`MAX_LAG_WARN` s (a delay that explains at least half of what lag 0
leaves unexplained) or scaled by more than :data:`SCALE_WARN`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["JointVelocity", "VelocityCheck", "check_velocity", "MIN_CORRELATION", "MAX_SCALE", "MAX_LAG",
           "MAX_LAG_WARN", "LAG_GAIN", "SCALE_WARN", "MIN_RANGE", "BAND_ENERGY", "BAND_FACTOR", "MIN_CUTOFF", "MAX_SAMPLES"]

#: below this correlation at every lag the logged v is not dq/dt (refused)
MIN_CORRELATION = 0.5
#: a scale of v over dq/dt beyond this factor (or negative) is another quantity or unit (refused)
MAX_SCALE = 2.0
#: lags searched [s] (± this, at most a quarter of the log)
MAX_LAG = 0.25
#: a lag of v behind (or ahead of) dq/dt longer than this [s] is reported (warned)
MAX_LAG_WARN = 0.005
#: ... and only when that lag leaves at most this share of the unexplained variance 1 − r² at lag 0 (a real
#: delay; a flat correlation peak, e.g. a velocity filtered differently from the derivative, is not one)
LAG_GAIN = 0.5
#: a scale off 1 by more than this share is reported (warned)
SCALE_WARN = 0.1
#: a joint whose q range is below this [rad or m] is not judged (its dq/dt is noise)
MIN_RANGE = 0.02
#: both signals are low-passed (zero phase, the same filter) at BAND_FACTOR × the frequency holding
#: BAND_ENERGY of the logged velocity's energy, at least MIN_CUTOFF [Hz]: the motion's band, where
#: the derivative of a noisy or quantized q is not noise
BAND_ENERGY = 0.95
BAND_FACTOR = 3.0
MIN_CUTOFF = 1.0
#: at most this many samples (the first ones) are compared: enough for a verdict on any log
MAX_SAMPLES = 200_000
#: another joint's dq/dt matches v "far better" when its correlation is above this and ≥ 0.2 above its own
OTHER_JOINT = 0.9


@dataclass(frozen=True)
class JointVelocity:
    """One joint: correlation of v with dq/dt at zero lag and at the best lag, the lag [s] (> 0: v
    lags behind dq/dt), the scale v ≈ scale · dq/dt at that lag, and the other joint whose dq/dt
    matches v best (``other``, ``other_correlation``; None when the joint's own matches best)."""

    joint: str
    correlation: float
    best_correlation: float
    lag: float
    scale: float
    other: str | None = None
    other_correlation: float | None = None

    def describe(self, lag: bool = True) -> str:
        """``'joint' r = 0.999 at lag 20 ms (0.990 at 0), v = 1.00·dq/dt`` (``lag``: with the best lag; else the
        correlation at lag 0), and ``, matches 'other' (r = 0.999)`` when another joint's dq/dt matches v."""
        if lag and self.lag:
            text = f"'{self.joint}' r = {self.best_correlation:.3f} at lag {1e3 * self.lag:.0f} ms ({self.correlation:.3f} at 0)"
        else:
            text = f"'{self.joint}' r = {self.correlation:.3f}"
        text += f", v = {self.scale:.3g}·dq/dt"
        if self.other is not None:
            text += f", matches '{self.other}' (r = {self.other_correlation:.3f})"
        return text


@dataclass(frozen=True)
class VelocityCheck:
    """The joints judged (:class:`JointVelocity`), those refused and those warned about (their names),
    and the joints not judged because they barely move."""

    joints: tuple[JointVelocity, ...] = ()
    refused: tuple[str, ...] = ()
    warned: tuple[str, ...] = ()
    still: tuple[str, ...] = field(default=())

    def _text(self, names, lag: bool) -> str:
        by = {j.joint: j for j in self.joints}
        more = f"; and {len(names) - 3} more" if len(names) > 3 else ""
        return "; ".join(by[n].describe(lag) for n in names[:3]) + more

    @property
    def refusal(self) -> str | None:
        """One line naming each refused joint with its figures, or None."""
        if not self.refused:
            return None
        return (f"the logged v is not the derivative of the logged q on joint(s) {self._text(self.refused, False)}: "
                "q and v swapped, v in other units, or another joint's column?")

    @property
    def warning(self) -> str | None:
        """One line naming each joint warned about with its figures, or None."""
        if not self.warned:
            return None
        return (f"the logged v differs from dq/dt on joint(s) {self._text(self.warned, True)}: a delayed or scaled "
                "velocity shifts the friction and inertia estimates")


def _band(v: np.ndarray, dt: float) -> float:
    """The low-pass cut-off [Hz] both signals are compared under: :data:`BAND_FACTOR` × the frequency
    below which :data:`BAND_ENERGY` of the logged velocity's energy lies (its motion, not its noise),
    within [:data:`MIN_CUTOFF`, 0.4 × Nyquist]."""
    x = v - v.mean(axis=0)
    power = (np.abs(np.fft.rfft(x, axis=0)) ** 2).sum(axis=1)
    freqs = np.fft.rfftfreq(len(x), dt)
    cum = np.cumsum(power)
    if not cum[-1] > 0:
        return 0.2 / dt
    f = float(freqs[min(int(np.searchsorted(cum, BAND_ENERGY * cum[-1])), len(freqs) - 1)])
    return float(np.clip(BAND_FACTOR * f, MIN_CUTOFF, 0.2 / dt))


def _lowpass(x: np.ndarray, cutoff: float, dt: float) -> np.ndarray:
    """Zero-phase low-pass with the gain of a 2nd-order Butterworth run forward and backward,
    |H(f)|² = 1 / (1 + (f/f_c)⁴), applied in the frequency domain (NumPy only: no SciPy import on the
    identify path) to the log reflected at both ends."""
    pad = min(len(x) - 1, max(1, int(round(2.0 / (cutoff * dt)))))
    xp = np.concatenate([2 * x[:1] - x[pad:0:-1], x, 2 * x[-1:] - x[-2:-pad - 2:-1]], axis=0)
    f = np.fft.rfftfreq(len(xp), dt)
    gain = 1.0 / (1.0 + (f / cutoff) ** 4)
    y = np.fft.irfft(np.fft.rfft(xp, axis=0) * gain[:, None] if xp.ndim == 2 else np.fft.rfft(xp) * gain,
                     n=len(xp), axis=0)
    return y[pad:pad + len(x)]


def _xcorr(a: np.ndarray, b: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Pearson correlation of ``a[n]`` with ``b[n − k]`` over their overlap, at lags k = −max_lag …
    max_lag (k > 0: ``a`` is ``b`` delayed by k samples); the products by FFT, the overlap's sums by
    cumulative sums, so each lag's correlation is exact."""
    n = len(a)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    circ = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)  # Σ a[m + k] b[m], k mod nfft
    lags = np.arange(-max_lag, max_lag + 1)
    sab = circ[lags % nfft]
    ca, cb = np.concatenate([[0.0], np.cumsum(a)]), np.concatenate([[0.0], np.cumsum(b)])
    caa, cbb = np.concatenate([[0.0], np.cumsum(a * a)]), np.concatenate([[0.0], np.cumsum(b * b)])
    lo_a, hi_a = np.maximum(lags, 0), n + np.minimum(lags, 0)   # a[lo_a:hi_a] meets b[lo_a - k: hi_a - k]
    lo_b, hi_b = lo_a - lags, hi_a - lags
    m = hi_a - lo_a
    sa, sb = ca[hi_a] - ca[lo_a], cb[hi_b] - cb[lo_b]
    var_a = caa[hi_a] - caa[lo_a] - sa * sa / m
    var_b = cbb[hi_b] - cbb[lo_b] - sb * sb / m
    den = np.sqrt(np.clip(var_a, 0, None) * np.clip(var_b, 0, None))
    return lags, np.divide(sab - sa * sb / m, den, out=np.zeros_like(den), where=den > 0)


def check_velocity(t: np.ndarray, q: np.ndarray, v: np.ndarray, joint_names) -> VelocityCheck:
    """Compare the logged ``v`` (N × n) with dq/dt of the logged ``q`` on time stamps ``t`` (module
    docstring). Pure: reads nothing, warns nothing; the caller refuses or warns with the text."""
    t, q, v = np.asarray(t, float), np.asarray(q, float), np.asarray(v, float)
    names = list(joint_names)
    n = min(len(t), MAX_SAMPLES)
    if n < 20 or q.shape != v.shape or q.ndim != 2:
        return VelocityCheck()
    t, q, v = t[:n], q[:n], v[:n]
    dt = float(np.median(np.diff(t)))
    if not np.isfinite(dt) or dt <= 0 or not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        return VelocityCheck()
    moving = [k for k in range(q.shape[1]) if np.ptp(q[:, k]) >= MIN_RANGE and np.std(v[:, k]) > 0]
    if not moving:
        return VelocityCheck(still=tuple(names))
    cutoff = _band(v[:, moving], dt)
    dq = _lowpass(np.gradient(q, t, axis=0), cutoff, dt)
    vs = _lowpass(v, cutoff, dt)
    moving = [k for k in moving if np.std(dq[:, k]) > 0]
    still = tuple(names[k] for k in range(q.shape[1]) if k not in moving)
    if not moving:
        return VelocityCheck(still=still)
    dz = dq[:, moving] - dq[:, moving].mean(axis=0)
    vz = vs[:, moving] - vs[:, moving].mean(axis=0)
    den = np.sqrt(np.outer((vz * vz).mean(axis=0), (dz * dz).mean(axis=0)))
    cross = np.divide(vz.T @ dz / len(dz), den, out=np.zeros_like(den), where=den > 0)  # v_i against dq_j
    max_lag = max(1, min(int(round(MAX_LAG / dt)), n // 4))
    out, refused, warned = [], [], []
    for i, k in enumerate(moving):
        lags, c = _xcorr(vz[:, i], dz[:, i], max_lag) if np.std(vz[:, i]) > 0 else (np.array([0]), np.array([0.0]))
        best = int(np.argmax(c))
        lag = int(lags[best])
        a, b = (vs[lag:, k], dq[:len(dq) - lag, k]) if lag >= 0 else (vs[:lag, k], dq[-lag:, k])
        scale = float(np.dot(a, b) / np.dot(b, b)) if np.dot(b, b) > 0 else float("nan")
        c0 = float(cross[i, i])
        others = [(float(cross[i, m]), moving[m]) for m in range(len(moving)) if m != i]
        other = max(others, default=(-1.0, None))
        match = other[1] is not None and other[0] > OTHER_JOINT and other[0] >= max(c0, float(c[best])) + 0.2
        jv = JointVelocity(names[k], c0, float(c[best]), lag * dt, scale,
                           names[other[1]] if match else None, other[0] if match else None)
        out.append(jv)
        off_scale = not np.isfinite(scale) or not 1 / MAX_SCALE <= scale <= MAX_SCALE
        if match or c0 <= -MIN_CORRELATION or (off_scale and float(c[best]) >= MIN_CORRELATION):
            refused.append(jv.joint)  # another joint's, against the motion, or the motion in other units
        elif float(c[best]) < MIN_CORRELATION or off_scale:  # weak evidence on its own: warned
            warned.append(jv.joint)
        elif (abs(lag * dt) > MAX_LAG_WARN and 1 - float(c[best]) ** 2 < LAG_GAIN * (1 - c0 ** 2)) or abs(scale - 1) > SCALE_WARN:
            warned.append(jv.joint)
    return VelocityCheck(tuple(out), tuple(refused), tuple(warned), still)

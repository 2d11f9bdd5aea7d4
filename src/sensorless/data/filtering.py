"""Filtering, differentiation and resampling of trajectories (thin layers over scipy.signal; the
Savitzky–Golay arithmetic is SciPy's, from :mod:`.savgol`, which avoids importing scipy.signal).

All operations act along axis 0 (samples), return a new :class:`Trajectory` and append
a note to ``units["processing"]`` saying what was done. Filters that assume a constant
sample period refuse logs whose period varies by more than 5 % (max |dt - median| /
median); resample those first with :func:`resample_uniform`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import DataError, setting
from .savgol import savgol_coeffs, savgol_filter
from .trajectory import Trajectory
from .validation import validate_trajectory
from ..errors import TooFewSamplesError

#: most samples a resampled log may have, per sample of the log
MAX_UPSAMPLE = 100

__all__ = [
    "DEFAULT_DERIVATIVE_SECONDS",
    "DEFAULT_SAVGOL_WINDOW",
    "MAX_UPSAMPLE",
    "default_savgol_window",
    "butter_lowpass",
    "lowpass",
    "lowpass_channels",
    "LOWPASS_FIELDS",
    "LOWPASS_EXTRAS",
    "sign_continuous",
    "SavitzkyGolay",
    "savgol_derivatives",
    "trim",
    "decimate",
    "resample_uniform",
    "MAX_JITTER",
]

MAX_JITTER = 0.05  # relative sample-period variation accepted as "uniform"
MIN_PERIOD, MAX_PERIOD = 1e-7, 1e3  # s: sample periods the filters accept (10 MHz .. 1 mHz)
_PER_SAMPLE = ("q", "v", "a", "tau", "base_q", "base_v", "base_a")


# ---- helpers --------------------------------------------------------------------
def note_processing(traj: Trajectory, text: str) -> dict[str, str]:
    """``traj.units`` with ``text`` appended to its ``processing`` record (``; ``-separated)."""
    units = dict(traj.units)
    units["processing"] = f"{units['processing']}; {text}" if units.get("processing") else text
    return units


def uniform_dt(traj: Trajectory, what: str) -> float:
    """Median sample period, or DataError if the sampling is not uniform."""
    if len(traj) < 2:
        raise TooFewSamplesError(f"{what} needs at least 2 samples, got {len(traj)}", traj.source)
    dt = np.diff(traj.t)
    med = float(np.median(dt))
    if not MIN_PERIOD <= med <= MAX_PERIOD:
        raise DataError(
            f"{what}: median sample period {med:.3g} s is outside [{MIN_PERIOD:g}, {MAX_PERIOD:g}] s; "
            f"is the time in the right unit ({setting('time_unit')}) or the rate ({setting('rate')}) right?", traj.source)
    jitter = float(np.max(np.abs(dt - med)) / med)
    if jitter > MAX_JITTER:
        raise DataError(
            f"{what} needs uniform sampling, but the sample period varies by {100 * jitter:.0f}% "
            f"(median {1e3 * med:.3f} ms, range {1e3 * dt.min():.3f}..{1e3 * dt.max():.3f} ms); "
            "resample first: resample_uniform(traj)",
            traj.source,
        )
    return med


def _per_sample_arrays(traj: Trajectory) -> dict[str, np.ndarray]:
    """Every per-sample array of ``traj`` (fields and extras with one row per sample)."""
    out = {n: getattr(traj, n) for n in _PER_SAMPLE if getattr(traj, n) is not None}
    for k, v in traj.extras.items():
        v = np.asarray(v)
        if v.ndim >= 1 and v.shape[0] == len(traj) and np.issubdtype(v.dtype, np.number):
            out[f"extras.{k}"] = v
    return out


def with_arrays(traj: Trajectory, arrays: dict[str, np.ndarray], **changes) -> Trajectory:
    """``traj`` with ``arrays`` (field name, or ``extras.NAME``) replaced, and ``changes``."""
    extras = dict(traj.extras)
    kw = {}
    for name, val in arrays.items():
        if name.startswith("extras."):
            extras[name[7:]] = val
        else:
            kw[name] = val
    return traj.with_(extras=extras, **kw, **changes)


# ---- Butterworth ---------------------------------------------------------------
def butter_lowpass(x: np.ndarray, cutoff_hz: float, rate_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass of ``x`` along axis 0 (``sosfiltfilt``).

    The forward-backward pass squares the magnitude response (-6 dB at ``cutoff_hz``,
    effective order ``2 * order``) and has no phase lag.
    """
    from scipy.signal import butter, sosfiltfilt  # imported on use: scipy.signal costs ~0.4 s at start-up

    x = np.asarray(x, dtype=float)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f"sample rate must be positive, got {rate_hz!r} Hz")
    if not 0 < cutoff_hz < rate_hz / 2:
        raise DataError(f"cutoff {cutoff_hz!r} Hz must lie in (0, {rate_hz / 2:g}) Hz (the Nyquist frequency)")
    if int(order) != order or order < 1:
        raise DataError(f"filter order must be a positive integer, got {order!r}")
    try:
        with np.errstate(all="raise"):
            sos = butter(int(order), cutoff_hz, btype="low", fs=rate_hz, output="sos")
    except (ArithmeticError, ValueError) as exc:
        raise DataError(f"cannot design a low-pass at {cutoff_hz!r} Hz for {rate_hz!r} Hz sampling ({exc})") from None
    padlen = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
    if x.shape[0] <= padlen:
        raise TooFewSamplesError(
            f"{x.shape[0]} samples are too few for an order-{order} zero-phase filter (need > {padlen})"
        )
    return sosfiltfilt(sos, x, axis=0)


#: Trajectory fields :func:`lowpass` filters by default; the base pose ``base_q``: its position, and its
#: quaternion made sign-continuous, filtered and renormalised
LOWPASS_FIELDS = ("q", "v", "a", "tau", "base_q", "base_v", "base_a")
#: ``extras`` it filters by default: the measured signals (motor currents, accelerometer, gyro, contact
#: wrenches, a ROS bag's wrench topics); contact flags and commands are left alone
LOWPASS_EXTRAS = ("current", "imu_acc", "imu_gyro", "contact_forces", "wrench")


def lowpass_channels(traj: Trajectory) -> list[str]:
    """The channels of ``traj`` that :func:`lowpass` filters by default (fields and extras present)."""
    return ([n for n in LOWPASS_FIELDS if getattr(traj, n) is not None]
            + [k for k in LOWPASS_EXTRAS if traj.extras.get(k) is not None])


def sign_continuous(quat: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions with the sign of each flipped where needed so that consecutive ones have a
    non-negative dot product (q and −q are the same rotation; filters and interpolation need continuity)."""
    quat = np.array(quat, dtype=float)
    if len(quat) > 1:
        flip = np.cumprod(np.where(np.sum(quat[1:] * quat[:-1], axis=1) < 0, -1.0, 1.0))
        quat[1:] *= flip[:, None]
    return quat


def lowpass(
    traj: Trajectory,
    cutoff_hz: float,
    order: int = 4,
    fields: Sequence[str] | None = None,
) -> Trajectory:
    """``traj`` with ``fields`` (trajectory fields or ``extras`` keys; default
    :func:`lowpass_channels`: every measured channel) low-passed by :func:`butter_lowpass`.
    Missing (None) fields are skipped. The base pose keeps unit quaternions (filtered sign-continuous,
    renormalised)."""
    traj = validate_trajectory(traj, check_units=False)
    dt = uniform_dt(traj, "lowpass")
    arrays: dict[str, np.ndarray] = {}
    for name in lowpass_channels(traj) if fields is None else fields:
        if name in _PER_SAMPLE:
            val, key = getattr(traj, name), name
        elif name in traj.extras:
            val, key = traj.extras[name], f"extras.{name}"
        else:
            raise DataError(f"lowpass: unknown field '{name}'; valid: {list(_PER_SAMPLE) + list(traj.extras)}", traj.source)
        if val is None:
            continue
        if name == "base_q":
            pos = with_source(butter_lowpass, traj.source, val[:, :3], cutoff_hz, 1.0 / dt, order)
            quat = with_source(butter_lowpass, traj.source, sign_continuous(val[:, 3:]), cutoff_hz, 1.0 / dt, order)
            arrays[key] = np.hstack([pos, quat / np.linalg.norm(quat, axis=1, keepdims=True)])
        else:
            arrays[key] = with_source(butter_lowpass, traj.source, val, cutoff_hz, 1.0 / dt, order)
    done = [k.removeprefix("extras.") for k in arrays]
    return with_arrays(traj, arrays, units=note_processing(traj, f"lowpass(butterworth order={order}, zero-phase, {cutoff_hz:g} Hz) of {done}"))


def with_source(fn, source: str, *args):
    """Call ``fn``; re-raise a DataError without a source with ``source`` attached."""
    try:
        return fn(*args)
    except DataError as exc:
        if exc.source is None:
            raise type(exc)(str(exc), source) from None
        raise


# ---- Savitzky-Golay --------------------------------------------------------------
@dataclass
class SavitzkyGolay:
    """Savitzky-Golay smoother/differentiator: a least-squares polynomial of degree
    ``polyorder`` fitted to ``window`` samples spaced ``dt`` apart, evaluated (or
    differentiated) at the window centre (``causal=False``) or at its newest sample
    (``causal=True``, uses only present and past samples).

    ``coeffs[d]`` are the dot-product weights (oldest sample first) of derivative ``d``
    in SI units (divided by ``dt**d``). Both variants are exact for polynomials of
    degree <= ``polyorder`` and have no delay on them (``delay`` = 0): the causal one
    evaluates the fit at the newest sample instead of lagging by half a window, at
    the price of a much higher noise gain (see :meth:`noise_gain`).

    Edges: the non-causal filter uses ``savgol_filter(mode="interp")`` (the fit of the
    first/last window evaluated at the edge samples). The causal one uses, for its first
    ``window - 1`` outputs (:attr:`warmup`), the fit of the first window; those outputs
    see up to ``window - 1`` future samples. Drop them when emulating a real-time estimator.
    """

    window: int
    polyorder: int
    dt: float
    causal: bool = False
    coeffs: dict[int, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if int(self.window) != self.window or self.window < 1 or self.window % 2 == 0:
            raise DataError(f"Savitzky-Golay window must be a positive odd integer, got {self.window!r}")
        if int(self.polyorder) != self.polyorder or not 0 <= self.polyorder < self.window:
            raise DataError(f"polyorder must be an integer in [0, window={self.window}), got {self.polyorder!r}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise DataError(f"dt must be a positive number of seconds, got {self.dt!r}")
        self.window, self.polyorder, self.dt = int(self.window), int(self.polyorder), float(self.dt)
        pos = self.window - 1 if self.causal else None
        try:
            with np.errstate(all="raise"):
                self.coeffs = {
                    d: savgol_coeffs(self.window, self.polyorder, deriv=d, delta=self.dt, pos=pos, use="dot")
                    for d in range(self.polyorder + 1)
                }
        except (ArithmeticError, ValueError) as exc:  # dt**d under/overflows for absurd sample periods
            raise DataError(f"Savitzky-Golay coefficients for dt={self.dt!r} s are not finite ({exc}); "
                            "check the time unit / rate") from None
        if not all(np.all(np.isfinite(c)) for c in self.coeffs.values()):
            raise DataError(f"Savitzky-Golay coefficients for dt={self.dt!r} s are not finite; check the time unit / rate")

    @property
    def delay(self) -> float:
        """Delay [s] on signals the polynomial fits exactly: 0 for both variants."""
        return 0.0

    @property
    def warmup(self) -> int:
        """Leading outputs that are not causal (``window - 1`` if causal, else 0)."""
        return self.window - 1 if self.causal else 0

    def noise_gain(self, deriv: int = 0) -> float:
        """Output std per unit white input noise std: ``||coeffs[deriv]||_2``."""
        return float(np.linalg.norm(self._coeffs(deriv)))

    def _coeffs(self, deriv: int) -> np.ndarray:
        if deriv not in self.coeffs:
            raise DataError(f"derivative order {deriv!r} must be in 0..polyorder={self.polyorder}")
        return self.coeffs[deriv]

    def apply(self, x: np.ndarray, deriv: int = 0) -> np.ndarray:
        """Smoothed signal (``deriv=0``) or its ``deriv``-th time derivative, along axis 0."""
        c = self._coeffs(deriv)
        x = np.asarray(x, dtype=float)
        w = self.window
        if x.ndim == 0 or x.shape[0] < w:
            n = 0 if x.ndim == 0 else x.shape[0]
            raise TooFewSamplesError(f"{n} samples are fewer than the Savitzky-Golay window ({w})")
        if not self.causal:
            return savgol_filter(x, w, self.polyorder, deriv=deriv, delta=self.dt, axis=0, mode="interp")
        y = np.empty_like(x)
        windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)  # (n-w+1, ..., w), oldest first
        y[w - 1 :] = windows @ c
        if w > 1:
            head = savgol_filter(x[:w], w, self.polyorder, deriv=deriv, delta=self.dt, axis=0, mode="interp")
            y[: w - 1] = head[: w - 1]
        return y


#: Savitzky–Golay window [samples] when none is given (polynomial order 3): the larger of this
#: and DEFAULT_DERIVATIVE_SECONDS at the log's rate (:func:`default_savgol_window`).
DEFAULT_SAVGOL_WINDOW = 11
#: default derivative window [s]: 0.2 s (21 samples at 100 Hz) passes motion up to ~6 Hz and
#: keeps the v̇ noise × inertia of a big joint below its torque noise on a 100 Hz arm
DEFAULT_DERIVATIVE_SECONDS = 0.2


def default_savgol_window(rate: float) -> int:
    """The one default Savitzky–Golay window [samples, odd] at ``rate`` [Hz]: max(11, 0.2 s).
    Every derivative in the package (joint v/v̇, base acceleration, IMU) defaults to it."""
    n = int(round(DEFAULT_DERIVATIVE_SECONDS * float(rate))) if math.isfinite(rate) and rate > 0 else 0
    return max(DEFAULT_SAVGOL_WINDOW, n + 1 - n % 2)


def savgol_derivatives(
    traj: Trajectory,
    window: int | None = None,
    polyorder: int = 3,
    causal: bool = False,
) -> Trajectory:
    """Smooth ``q`` and replace ``v``, ``a`` by its first and second Savitzky-Golay
    derivatives. ``window`` defaults to :func:`default_savgol_window` (0.2 s, at least 11)."""
    traj = validate_trajectory(traj, check_units=False)
    dt = uniform_dt(traj, "savgol_derivatives")
    if polyorder < 2:
        raise DataError(f"polyorder must be >= 2 to estimate accelerations, got {polyorder}", traj.source)
    if window is None:
        window = max(default_savgol_window(1.0 / dt), polyorder + 2 if polyorder % 2 else polyorder + 1)
    sg = with_source(SavitzkyGolay, traj.source, window, polyorder, dt, causal)
    q = with_source(sg.apply, traj.source, traj.q, 0)
    v = sg.apply(traj.q, 1)
    a = sg.apply(traj.q, 2)
    kind = "causal" if causal else "centred"
    note = f"savgol({kind}, window={sg.window}, polyorder={polyorder}, dt={dt:.6g} s): q smoothed; v, a = d/dt, d2/dt2 of q"
    return traj.with_(q=q, v=v, a=a, units=note_processing(traj, note))


# ---- selection and resampling ------------------------------------------------------
def trim(
    traj: Trajectory,
    t_start: float | None = None,
    t_end: float | None = None,
    *,
    relative: bool = False,
) -> Trajectory:
    """Samples with ``t_start <= t <= t_end`` (either bound optional). With
    ``relative=True`` the bounds are seconds after ``traj.t[0]``."""
    t0 = float(traj.t[0]) if relative and len(traj) else 0.0
    lo = -np.inf if t_start is None else t0 + t_start
    hi = np.inf if t_end is None else t0 + t_end
    if lo > hi:
        raise DataError(f"trim: t_start={t_start} is after t_end={t_end}", traj.source)
    mask = (traj.t >= lo) & (traj.t <= hi)
    if not mask.any():
        span = f"[{traj.t[0]:.3f}, {traj.t[-1]:.3f}] s" if len(traj) else "empty"
        raise TooFewSamplesError(f"trim: no sample in [{t_start}, {t_end}] (log spans {span})", traj.source)
    out = traj.take(mask)
    return out.with_(units=note_processing(out, f"trim({t_start}, {t_end}{', relative' if relative else ''})"))


def decimate(traj: Trajectory, factor: int, antialias: bool = True) -> Trajectory:
    """Every ``factor``-th sample. With ``antialias`` the per-sample signals (not ``t``,
    not the base orientation quaternion) are first low-passed at 0.8 x the new Nyquist
    frequency with :func:`butter_lowpass` (zero-phase, order 4)."""
    if int(factor) != factor or factor < 1:
        raise DataError(f"decimate: factor must be a positive integer, got {factor!r}", traj.source)
    factor = int(factor)
    if factor == 1:
        return traj.with_()
    note = f"decimate(x{factor}"
    if antialias:
        traj = validate_trajectory(traj, check_units=False)
        rate = 1.0 / uniform_dt(traj, "decimate")
        cutoff = 0.8 * rate / (2 * factor)
        arrays = {}
        for name, val in _per_sample_arrays(traj).items():
            if name == "base_q":
                val = val.copy()
                val[:, :3] = with_source(butter_lowpass, traj.source, val[:, :3], cutoff, rate)
                arrays[name] = val
            else:
                arrays[name] = with_source(butter_lowpass, traj.source, val, cutoff, rate)
        traj = with_arrays(traj, arrays)
        note += f", anti-alias low-pass {cutoff:g} Hz"
    out = traj.take(slice(None, None, factor))
    return out.with_(units=note_processing(out, note + ")"))


def resample_uniform(traj: Trajectory, rate_hz: float | None = None) -> Trajectory:
    """Linear interpolation of every per-sample array onto ``t[0] + k / rate_hz``
    (``k = 0 .. floor(duration * rate_hz)``); default rate is 1 / median dt. The base
    quaternion is renormalised after interpolation."""
    from scipy.interpolate import make_interp_spline

    traj = validate_trajectory(traj, check_units=False)
    rate = traj.rate if rate_hz is None else float(rate_hz)
    if not (np.isfinite(rate) and rate > 0):
        raise DataError(f"resample_uniform: rate must be a positive number of Hz, got {rate_hz!r}", traj.source)
    t0 = float(traj.t[0])
    rel = traj.t - t0
    n_given = len(traj.t)
    if rel[-1] * rate + 1 > MAX_UPSAMPLE * max(n_given, 1):  # 1e12 Hz would allocate TiB
        raise DataError(f"resampling at {rate:g} Hz would make {rel[-1] * rate + 1:.3g} samples of the log's "
                        f"{n_given} (more than {MAX_UPSAMPLE}×); choose a rate near the log's own", traj.source)
    n = int(np.floor(rel[-1] * rate + 1e-9)) + 1
    t_new = np.arange(n) / rate
    arrays = {}
    for name, val in _per_sample_arrays(traj).items():
        if name == "base_q":
            val = np.hstack([val[:, :3], sign_continuous(val[:, 3:])])
        arrays[name] = make_interp_spline(rel, np.asarray(val, dtype=float), k=1, axis=0)(t_new)
    if "base_q" in arrays:
        quat = arrays["base_q"][:, 3:]
        arrays["base_q"][:, 3:] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return with_arrays(traj, arrays, t=t0 + t_new, units=note_processing(traj, f"resample_uniform({rate:g} Hz, linear)"))

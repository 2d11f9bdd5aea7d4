"""One preprocessing path for logs, shared by the Python API and every CLI command.

:func:`prepare` runs, in this order:

1. **trim** to a time window (:class:`TrimWindow`: ``"1.9:49.6"`` = seconds after the
   first sample, a negative number counts back from the last sample, ``"abs:A:B"``
   uses the log's own time stamps; either end may be left open, ``":49.6"``);
2. **resample** (``"auto"``: only when the stamps are not uniform — duplicates, or a
   step more than ``jitter_tolerance`` off the median period; ``"off"``; or a rate in Hz)
   with :func:`sensorless.data.resample.resample` (gaps over ``max_gap`` periods are errors);
3. **low-pass** (zero-phase Butterworth, :func:`~sensorless.data.filtering.lowpass`);
4. **derivatives**, keeping what was logged: a logged v is kept and differentiated once,
   v̇ = d/dt v (Savitzky–Golay); only without a logged v are v and v̇ taken from q
   (d/dt q, d²/dt² q). ``velocity="from-q"`` forces the latter. A logged v̇ is kept
   unless ``savgol_window`` is given;
5. **rest** (``rest="auto"``, with a logged v): a joint whose |v| stays within 5 noise stds
   of zero and whose q moves less than 8 noise stds over the derivative window is at rest,
   v = v̇ = 0 there, unless it drifts consistently in one direction (creeping under load: v =
   its measured drift, v̇ = 0)
   (:mod:`sensorless.data.rest`; no friction chatter through sgn(noise) at rest);
6. **decimate** (anti-aliased).

``Trajectory.provenance`` records which signals were logged and which derived (and
how), the drive gains, the trim window, the timing and the resampling.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError, DataWarning, OptionError, TimestampError
from .filtering import MAX_JITTER, SavitzkyGolay, _note, _with_source, savgol_derivatives
from .filtering import DEFAULT_DERIVATIVE_SECONDS, DEFAULT_SAVGOL_WINDOW, default_savgol_window
from .filtering import decimate as _decimate
from .filtering import lowpass as _lowpass
from .filtering import trim as _trim
from .limits import current_options, read_options
from .plausibility import check_gain_plausibility
from .rest import REST_MODES, signal_noise, zero_at_rest
from .resample import DEFAULT_MAX_GAP, resample as _resample, timing
from .trajectory import Trajectory
from .validation import TooFewSamplesError, validate_trajectory

__all__ = ["prepare", "load_log", "check_preprocessing", "parse_columns", "TrimWindow", "parse_resample", "DEFAULT_SAVGOL_WINDOW", "VELOCITY_SOURCES",
           "DEFAULT_DERIVATIVE_SECONDS", "default_savgol_window"]

VELOCITY_SOURCES = ("logged", "from-q")
#: ``resample="auto"`` refuses a log in which more than this share of the time steps are duplicates
MAX_DUPLICATE_SHARE = 0.1
_POLYORDER = 3


@dataclass(frozen=True)
class TrimWindow:
    """A time window ``[start, end]`` [s]; ``None`` is an open end.

    Relative (default): seconds after the first sample, a negative value counts back
    from the last sample (``-2`` = 2 s before the end). ``absolute``: the log's stamps.
    """

    start: float | None = None
    end: float | None = None
    absolute: bool = False

    @classmethod
    def parse(cls, spec: "str | tuple | TrimWindow") -> "TrimWindow":
        """``"1.9:49.6"``, ``":49.6"``, ``"1.9:"``, ``"2:-1.5"``, ``"abs:1712.3:1760"``, or ``(start, end)``."""
        if isinstance(spec, TrimWindow):
            return spec
        if isinstance(spec, (tuple, list)):
            if len(spec) != 2:
                raise DataError(f"trim window must be (start, end), got {spec!r}")
            return cls(*(None if v is None else _seconds(v, spec) for v in spec))
        if not isinstance(spec, str):
            raise DataError(f"trim window must be 'START:END' or (start, end), got {spec!r}")
        text = spec.strip()
        absolute = text.lower().startswith("abs:")
        body = text[4:] if absolute else text
        parts = body.split(":")
        if len(parts) != 2:
            raise DataError(f"trim window '{spec}' is not START:END seconds (e.g. '1.9:49.6', ':49.6', 'abs:100:160')")
        start, end = (None if not p.strip() else _seconds(p, spec) for p in parts)
        return cls(start, end, absolute)

    def bounds(self, t: np.ndarray) -> tuple[float, float]:
        """Absolute ``(lo, hi)`` on the time axis ``t``."""
        t0, t1 = float(t[0]), float(t[-1])

        def at(v: float | None, open_end: float) -> float:
            if v is None:
                return open_end
            if self.absolute:
                return v
            return t0 + v if v >= 0 else t1 + v

        return at(self.start, -np.inf), at(self.end, np.inf)

    def __str__(self) -> str:
        fmt = lambda v: "" if v is None else f"{v:g}"  # noqa: E731
        return ("abs:" if self.absolute else "") + f"{fmt(self.start)}:{fmt(self.end)}"


def _seconds(text: Any, spec: Any) -> float:
    try:
        val = float(text)
    except (TypeError, ValueError):
        raise DataError(f"trim window {spec!r}: {text!r} is not a number of seconds") from None
    if not np.isfinite(val):
        raise DataError(f"trim window {spec!r}: {text!r} is not a finite number of seconds")
    return val


def trim_window(traj: Trajectory, window: "str | tuple | TrimWindow") -> Trajectory:
    """Samples of ``traj`` inside ``window`` (typed errors if it is empty or outside the log)."""
    src = traj.source
    win = _with_source(TrimWindow.parse, src, window)
    t = traj.t
    lo, hi = win.bounds(t)
    span = f"the log spans {t[0]:.6g}..{t[-1]:.6g} s ({t[-1] - t[0]:.3f} s)"
    if lo >= hi:
        raise DataError(f"trim window '{win}' is empty: start {lo:.6g} s is not before end {hi:.6g} s; {span}", src)
    if lo > t[-1] or hi < t[0]:
        raise DataError(f"trim window '{win}' = [{lo:.6g}, {hi:.6g}] s lies outside the log: {span}", src)
    n = int(np.sum((t >= lo) & (t <= hi)))
    if n < 2:
        raise TooFewSamplesError(f"trim window '{win}' = [{lo:.6g}, {hi:.6g}] s holds {n} sample(s); {span}", src)
    out = _trim(traj, None if not np.isfinite(lo) else lo, None if not np.isfinite(hi) else hi)
    return out.with_(provenance={**out.provenance, "trim": {"window": str(win), "t_start": float(out.t[0]),
                                                             "t_end": float(out.t[-1]), "samples": len(out)}})


def parse_resample(spec: "str | float | None") -> "str | float":
    """``"auto"`` | ``"off"`` | a rate in Hz (number or numeric string)."""
    if spec is None:
        return "auto"
    if isinstance(spec, str):
        s = spec.strip().lower()
        if s in ("auto", "off"):
            return s
        if s in ("none", "no", "false"):
            return "off"
        try:
            spec = float(s.removesuffix("hz"))
        except ValueError:
            raise DataError(f"resample must be 'auto', 'off' or a rate in Hz, got {spec!r}") from None
    rate = float(spec)
    if not (np.isfinite(rate) and rate > 0):
        raise DataError(f"resample rate must be a positive number of Hz, got {spec!r}")
    return rate


def _velocity_source(velocity: str) -> str:
    v = str(velocity).strip().lower().replace("_", "-")
    v = {"q": "from-q", "position": "from-q"}.get(v, v)
    if v not in VELOCITY_SOURCES:
        raise DataError(f"velocity must be one of {list(VELOCITY_SOURCES)}, got {velocity!r}")
    return v


def prepare(
    traj: Trajectory,
    *,
    trim: "str | tuple | TrimWindow | None" = None,
    resample: "str | float | None" = "auto",
    lowpass: float | None = None,
    savgol_window: int | None = None,
    velocity: str = "logged",
    decimate: int = 1,
    max_gap: float = DEFAULT_MAX_GAP,
    jitter_tolerance: float = MAX_JITTER,
    rest: str = "auto",
) -> Trajectory:
    """Trim, resample, low-pass, differentiate and decimate ``traj`` (module docstring).

    ``savgol_window`` [samples, odd] re-derives v̇ (and v when it comes from q) even if
    logged; default :func:`default_savgol_window` (0.2 s, at least 11 samples) when a
    derivative is missing.
    """
    src = traj.source
    mode = parse_resample(resample)
    vel = _velocity_source(velocity)
    prov = dict(traj.provenance)
    for f in ("q", "v", "a", "tau"):
        if getattr(traj, f) is not None:
            prov.setdefault(f, "logged")
    traj = traj.with_(provenance=prov)

    if trim is not None:
        traj = trim_window(traj, trim)

    info = timing(traj.t, src)
    prov = {**traj.provenance, "timing": info.to_dict()}
    traj = traj.with_(provenance=prov)
    if mode == "off":
        if info.duplicates:
            dt = np.diff(traj.t)
            i = int(np.flatnonzero(dt == 0)[0]) + 1
            raise TimestampError(
                f"duplicate timestamp at sample {i} (t={traj.t[i]:.6f} s; {info.duplicates} in total) and "
                "resampling is off; use --resample auto (resample='auto') to merge duplicates", src)
    elif mode == "auto":
        if info.duplicates > MAX_DUPLICATE_SHARE * (len(traj.t) - 1):
            raise TimestampError(
                f"{info.duplicates} of {len(traj.t) - 1} time steps ({100 * info.duplicates / (len(traj.t) - 1):.0f} %) "
                "repeat the previous stamp: the time column is coarser than the sampling, or every sample is logged "
                "more than once; --resample auto will not guess which. Give the rate: --resample RATE_HZ merges the "
                "duplicates and interpolates at that rate; if the samples themselves are uniform (a clock too coarse "
                "for the rate), remove the time column and pass --rate HZ", src)
        if not info.is_uniform(jitter_tolerance):
            traj = _resample(traj, max_gap=max_gap)
            r = traj.provenance["resampled"]
            warnings.warn(f"{src}: --resample auto: the time stamps are not uniform ({info.duplicates} duplicate(s), "
                          f"max step deviation {100 * info.max_deviation:.0f} %); merged {info.duplicates} duplicate "
                          f"sample(s) and interpolated {info.n_samples - info.duplicates} onto {len(traj.t)} samples at "
                          f"{r['rate_hz']:.6g} Hz", DataWarning, stacklevel=2)
    else:
        traj = _resample(traj, mode, max_gap=max_gap)
    traj = validate_trajectory(traj, check_units=False)

    derive_v = traj.v is None or vel == "from-q"
    derive_a = derive_v or traj.a is None or savgol_window is not None
    base_a = traj.base_v is not None and traj.base_q is not None and (traj.base_a is None or savgol_window is not None)
    steps = [name for name, on in (("lowpass", lowpass), ("derivatives", derive_a), ("decimate", decimate > 1),
                                    ("base acceleration", base_a)) if on]
    if steps and mode == "off":
        now = timing(traj.t, src)
        if not now.is_uniform(jitter_tolerance):
            raise DataError(
                f"{' and '.join(steps)} need(s) uniform sampling but resampling is off and the time stamps are not "
                f"uniform ({now}); use --resample auto (resample='auto') or a rate in Hz", src)

    if rest not in REST_MODES:
        raise OptionError(f"--rest must be one of {', '.join(REST_MODES)}, got {rest!r}")
    sigma_v = None
    if rest == "auto" and not derive_v and len(traj) > 3 * DEFAULT_SAVGOL_WINDOW:
        sigma_v = signal_noise(traj.v)  # before the low-pass colours it (sensorless.data.rest)
        sigma_q = signal_noise(traj.q)
    if lowpass:
        traj = _lowpass(traj, lowpass)
        traj = traj.with_(provenance={**traj.provenance, "lowpass_hz": float(lowpass)})

    w = int(savgol_window) if savgol_window is not None else default_savgol_window(
        1.0 / float(np.median(np.diff(traj.t))) if len(traj.t) > 1 and np.median(np.diff(traj.t)) > 0 else float("nan"))
    if derive_v:
        traj = savgol_derivatives(traj, window=w, polyorder=_POLYORDER)
        how = f"Savitzky-Golay (window {w}, order {_POLYORDER})"
        traj = traj.with_(provenance={
            **traj.provenance, "q": traj.provenance.get("q", "logged") + f", smoothed by {how}",
            "v": f"derived: d/dt q, {how}", "a": f"derived: d²/dt² q, {how}"})
    elif derive_a:
        dt = float(np.median(np.diff(traj.t)))
        sg = _with_source(SavitzkyGolay, src, w, _POLYORDER, dt)
        a = _with_source(sg.apply, src, traj.v, 1)
        how = f"Savitzky-Golay (window {w}, order {_POLYORDER})"
        traj = traj.with_(a=a, units=_note(traj, f"savgol(centred, window={w}, polyorder={_POLYORDER}): a = d/dt of logged v"),
                          provenance={**traj.provenance, "a": f"derived: d/dt of logged v, {how}"})
    if sigma_v is not None:
        traj = zero_at_rest(traj, sigma_v, w, sigma_q)
    if base_a:
        from .imu import base_acceleration  # imported on use: it loads Pinocchio

        traj = base_acceleration(traj, window=w)
        traj = traj.with_(provenance={**traj.provenance, "base_a": "derived (base_acceleration)"})
    if decimate and decimate > 1:
        traj = _decimate(traj, decimate)
        traj = traj.with_(provenance={**traj.provenance, "decimate": int(decimate)})
    return traj


def parse_columns(spec: "str | None") -> "dict | None":
    """'q=0:7;v=vel_{joint};tau=a|b|c' -> {'q': '0:7', 'v': 'vel_{joint}', 'tau': ['a','b','c']}.

    A field may carry per-joint drive gains for currents, 'tau=i_{joint}:gain=10,10.7,...'
    (``i_*`` = ``i_{joint}``); they stay on the entry (the last item of a list) for the
    reader (:func:`sensorless.data.gains.split_gain_modifiers`).
    """
    if not spec:
        return None
    out: dict = {}
    for part in spec.split(";"):
        if not part.strip():
            continue
        if "=" not in part:
            raise OptionError(f"--columns: '{part}' is not FIELD=SPEC (e.g. 'q=0:7;tau=14:21')")
        key, val = (s.strip() for s in part.split("=", 1))
        out[key] = val.split("|") if "|" in val else val
    return out


PREPROCESSING_KEYS = ("columns", "gains", "rate", "resample", "lowpass", "savgol_window", "velocity", "max_gap",
                      "rest", "time_unit")
"""Options a model remembers in result.json (settings.preprocessing) and predict/estimate-force reuse.
The trim window and decimation belong to one log and are recorded but not reused."""


def check_preprocessing(rate, lowpass, savgol_window, decimate) -> None:
    """OptionError for preprocessing options no log can use (zero, negative, NaN, absurd)."""
    from .readers import MAX_RATE, MIN_RATE

    if rate is not None and not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
        raise OptionError(f"--rate must be a sample rate in [{MIN_RATE:g}, {MAX_RATE:g}] Hz, got {rate!r}")
    if lowpass is not None and not (math.isfinite(lowpass) and lowpass > 0):
        raise OptionError(f"--lowpass must be a cut-off frequency > 0 Hz, got {lowpass!r}")
    if savgol_window is not None and (savgol_window < 5 or savgol_window % 2 == 0):
        raise OptionError(f"--savgol-window must be an odd number of samples >= 5, got {savgol_window!r}")
    if decimate is not None and decimate < 1:
        raise OptionError(f"--decimate must be an integer >= 1, got {decimate!r}")


def with_imu_frame(traj: Trajectory, robot, frame: str, savgol_window: int | None = None) -> Trajectory:
    """``traj`` with base_a rebuilt from its accelerometer ('imu_acc') read in model frame
    ``frame`` (:func:`~sensorless.data.imu.base_acceleration`); the derivative window is
    ``savgol_window``, else the default at the log's rate (as for v̇)."""
    from .imu import base_acceleration

    return base_acceleration(traj, window=savgol_window or default_savgol_window(1.0 / traj.dt), robot=robot,
                             imu_frame=frame)


def load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, *, gains=None, trim=None,
             resample="auto", velocity="logged", max_gap=None, outliers: str = "error", rest=None, time_unit=None,
             max_memory=None, allow_external=None, skip_bad=None, accept_implausible_gains=None):
    """Read, validate and preprocess one log (:func:`sensorless.data.prepare`).

    The one preprocessing function of both the local path (``sensorless.cli.common.load_logs``) and the Dask
    workers (:class:`sensorless.regressor.distributed.LogReader`), so both see the same samples.
    ``outliers`` ("error" | "drop" | "keep") is applied to the raw log; a log that lost samples
    that way is resampled onto its uniform grid even with ``resample="off"``. ``max_memory``,
    ``allow_external``, ``skip_bad`` and ``accept_implausible_gains``: :func:`sensorless.data.limits.read_options`.
    """
    with read_options(max_memory=max_memory, allow_external=allow_external, skip_bad=skip_bad,
                      accept_implausible_gains=accept_implausible_gains):
        return _load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, gains, trim, resample,
                         velocity, max_gap, outliers, rest, time_unit)


def _load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, gains, trim, resample, velocity, max_gap,
              outliers, rest, time_unit):
    from .outliers import OUTLIER_MODES
    from .readers import read_trajectory

    check_preprocessing(rate, lowpass, savgol_window, decimate)
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"--outliers must be one of {', '.join(OUTLIER_MODES)}, got {outliers!r}")
    mode = parse_resample(resample)
    cols = parse_columns(columns) if isinstance(columns, str) else columns
    if isinstance(gains, str) and gains.strip().lower() in ("off", "none"):
        gains = None
    traj = read_trajectory(path, columns=cols, rate=rate, robot=robot, gains=gains, time_unit=time_unit,
                           allow_duplicate_times=mode != "off", outliers=outliers)
    dropped = "outlier" in traj.units.get("processing", "")
    out = prepare(traj, trim=trim, resample="auto" if dropped and mode == "off" else mode, lowpass=lowpass,
                   savgol_window=savgol_window, velocity=velocity or "logged", decimate=decimate or 1,
                   max_gap=DEFAULT_MAX_GAP if max_gap is None else max_gap, rest=rest or "auto")
    if not current_options().get("accept_implausible_gains"):
        check_gain_plausibility(out, robot)  # τ = K·i against the model's torque scale, per joint
    return out

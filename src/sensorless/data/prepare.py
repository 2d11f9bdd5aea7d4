"""One preprocessing path for logs, shared by the Python API and every CLI command.

:func:`prepare` runs, in this order:

1. **trim** to a time window (:class:`TrimWindow`: ``"1.9:49.6"`` = seconds after the
   first sample, a negative number counts back from the last sample, ``"abs:A:B"``
   uses the log's own time stamps; either end may be left open, ``":49.6"``); with the base
   twist taken from the logged base pose (``base_velocity``), the samples before the first
   and after the last valid pose are clipped, with a warning counting them
   (:func:`~sensorless.data.base_pose.clip_to_pose`). :func:`load_log`
   cuts the window while reading instead, before the time axis is checked, after dropping a corrupt
   prefix/suffix (``skip_bad_rows``, :mod:`sensorless.data.bad_rows`);
2. **resample** (``"auto"``: only when the stamps are not uniform — duplicates, or a
   step more than ``jitter_tolerance`` off the median period; ``"off"``; or a rate in Hz)
   with :func:`sensorless.data.resample.resample` (gaps over ``max_gap`` periods are errors);
3. **base pose** → base twist and acceleration
   (:func:`~sensorless.data.base_pose.base_motion_from_pose`, from the pose samples as logged,
   low-passed at the same cut-off and differentiated with the same window as the joints);
   **wrench frames**: wrenches logged in model frames are expressed in world axes at the
   contact frames (:func:`~sensorless.data.wrench_frames.express_wrenches`);
4. **low-pass** (zero-phase Butterworth, :func:`~sensorless.data.filtering.lowpass`) of every
   measured channel (:func:`~sensorless.data.filtering.lowpass_channels`: q, v, v̇, τ, the base
   pose, twist and acceleration, motor currents, IMU, contact wrenches), recorded in
   ``provenance["lowpass"]``;
5. **derivatives**, keeping what was logged: a logged v is kept and differentiated once,
   v̇ = d/dt v (Savitzky–Golay); only without a logged v are v and v̇ taken from q
   (d/dt q, d²/dt² q). ``velocity="from-q"`` forces the latter. A logged v̇ is kept
   unless ``savgol_window`` is given. A log with contact flags gets a default window of at most
   a quarter of its median contact phase, and each stance is widened by half the window (the
   smoothed accelerations near a touchdown carry the impact);
6. **rest** (``rest="auto"``, with a logged v): a joint whose |v| stays within 5 noise stds
   of zero and whose q moves less than 8 noise stds over the derivative window is at rest,
   v = v̇ = 0 there, unless it drifts consistently in one direction (creeping under load: v =
   its measured drift, v̇ = 0)
   (:mod:`sensorless.data.rest`; no friction chatter through sgn(noise) at rest);
7. **base acceleration** from the accelerometer or the base twist (:mod:`sensorless.data.imu`);
8. **decimate** (anti-aliased).

``Trajectory.provenance`` records which signals were logged and which derived (and
how), each logged channel's quantization step and decimals (``resolution``,
:mod:`sensorless.data.resolution`, read before any resampling; they floor the noise of the rest
detection), the drive gains, the trim window, the timing and the resampling.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import DataError, DataWarning, OptionError, TimestampError, setting
from .filtering import MAX_JITTER, SavitzkyGolay, note_processing, with_source, savgol_derivatives
from .filtering import DEFAULT_DERIVATIVE_SECONDS, DEFAULT_SAVGOL_WINDOW, default_savgol_window
from .filtering import decimate as _decimate
from .filtering import lowpass as _lowpass
from .filtering import lowpass_channels
from .filtering import trim as _trim
from .limits import current_options, read_options
from .integrity import check_integrity
from .plausibility import check_gain_plausibility
from .imu import IMU_KEY
from .resolution import record_floor, resolution_record
from .rest import REST_MODES, signal_noise, zero_at_rest
from .resample import DEFAULT_MAX_GAP, resample as _resample, timing
from .trajectory import Trajectory
from .trims import LogTrims, TrimWindow, trim_window
from .validation import validate_trajectory
from .velocity_check import check_velocity

__all__ = ["prepare", "load_log", "check_preprocessing", "parse_columns", "parse_resample", "VELOCITY_SOURCES",
           "BASE_VELOCITY_SOURCES"]

VELOCITY_SOURCES = ("logged", "from-q")
#: where the base twist comes from: ``auto`` (from the logged base pose when no base velocity is logged),
#: ``from-pose`` (always, :func:`~sensorless.data.base_pose.base_motion_from_pose`), ``logged``
BASE_VELOCITY_SOURCES = ("auto", "from-pose", "logged")
#: ``resample="auto"`` refuses a log in which more than this share of the time steps are duplicates
MAX_DUPLICATE_SHARE = 0.1
_POLYORDER = 3


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


def _from_pose(base_velocity: str, traj: Trajectory, robot) -> bool:
    """Whether the base twist is derived from the logged base pose (``BASE_VELOCITY_SOURCES``; "auto":
    a log with ``base_q`` and no ``base_v``, unless ``robot`` is fixed-base)."""
    mode = str(base_velocity).strip().lower().replace("_", "-")
    if mode not in BASE_VELOCITY_SOURCES:
        raise OptionError(f"{setting('base_velocity')} must be one of {', '.join(BASE_VELOCITY_SOURCES)}, got "
                          f"{base_velocity!r}")
    if mode == "from-pose" and traj.base_q is None:
        raise DataError(f"{setting('base_velocity', 'from-pose')}: the log has no base pose ('base_q': x y z qx qy qz qw)",
                        traj.source)
    floating = robot is None or getattr(robot, "floating_base", False)
    return traj.base_q is not None and (mode == "from-pose" or (mode == "auto" and traj.base_v is None and floating))


def _check_logged_velocity(traj: Trajectory) -> None:
    """Refuse a logged v that is not dq/dt, warn about a delayed or scaled one (:mod:`.velocity_check`)."""
    check = check_velocity(traj.t, traj.q, traj.v, traj.joint_names)
    if check.refusal:
        raise DataError(f"{check.refusal} Check the columns ({setting('columns')}); if q is right, "
                        f"{setting('velocity', 'from-q')} derives v from q", traj.source)
    if check.warning:
        warnings.warn(f"{traj.source}: {check.warning}", DataWarning, stacklevel=3)


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
    base_velocity: str = "auto",
    pose_max_gap: float | None = None,
    robot=None,
    wrench_frames: "dict[str, str] | None" = None,
) -> Trajectory:
    """Trim, resample, low-pass, differentiate and decimate ``traj`` (module docstring).

    ``savgol_window`` [samples, odd] re-derives v̇ (and v when it comes from q) even if
    logged; default :func:`default_savgol_window` (0.2 s, at least 11 samples) when a
    derivative is missing. ``base_velocity``: "auto" (the base twist from ``base_q`` when no
    ``base_v`` is logged), "from-pose" or "logged"; ``pose_max_gap`` [median pose periods]:
    :func:`~sensorless.data.base_pose.clean_base_pose`. ``wrench_frames`` ``{contact frame:
    model frame}`` (with ``robot``): :func:`~sensorless.data.wrench_frames.express_wrenches`.
    """
    src = traj.source
    mode = parse_resample(resample)
    vel = _velocity_source(velocity)
    prov = dict(traj.provenance)
    for f in ("q", "v", "a", "tau", "base_q", "base_v", "base_a"):
        if getattr(traj, f) is not None:
            prov.setdefault(f, "logged")
    prov["resolution"] = resolution_record(traj)  # as logged: a resampling or low-pass hides it
    traj = traj.with_(provenance=prov)
    if wrench_frames and robot is None:
        raise OptionError("wrench frames need the robot model (prepare(..., robot=...))")

    if trim is not None:
        traj = trim_window(traj, trim)
    from_pose = _from_pose(base_velocity, traj, robot)
    if from_pose:  # imported on use: SciPy's interpolation and rotations
        from .base_pose import DEFAULT_POSE_MAX_GAP, base_motion_from_pose, clip_to_pose

        traj = clip_to_pose(traj)
        pose_samples = (traj.t.copy(), traj.base_q.copy())

    info = timing(traj.t, src)
    prov = {**traj.provenance, "timing": info.to_dict()}
    traj = traj.with_(provenance=prov)
    if mode == "off":
        if info.duplicates:
            dt = np.diff(traj.t)
            i = int(np.flatnonzero(dt == 0)[0]) + 1
            raise TimestampError(
                f"duplicate timestamp at sample {i} (t={traj.t[i]:.6f} s; {info.duplicates} in total) and "
                f"resampling is off; use {setting('resample', 'auto')} to merge duplicates", src)
    elif mode == "auto":
        if info.duplicates > MAX_DUPLICATE_SHARE * (len(traj.t) - 1):
            raise TimestampError(
                f"{info.duplicates} of {len(traj.t) - 1} time steps ({100 * info.duplicates / (len(traj.t) - 1):.0f} %) "
                "repeat the previous stamp: the time column is coarser than the sampling, or every sample is logged "
                f"more than once; {setting('resample', 'auto')} will not guess which. Give the rate: "
                f"{setting('resample', placeholder='RATE_HZ')} merges the duplicates and interpolates at that rate; if "
                "the samples themselves are uniform (a clock too coarse for the rate), remove the time column and give "
                f"{setting('rate', placeholder='HZ')}", src)
        if not info.is_uniform(jitter_tolerance):
            traj = _resample(traj, max_gap=max_gap)
            r = traj.provenance["resampled"]
            warnings.warn(f"{src}: {setting('resample', 'auto')}: the time stamps are not uniform ({info.duplicates} duplicate(s), "
                          f"max step deviation {100 * info.max_deviation:.0f} %); merged {info.duplicates} duplicate "
                          f"sample(s) and interpolated {info.n_samples - info.duplicates} onto {len(traj.t)} samples at "
                          f"{r['rate_hz']:.6g} Hz", DataWarning, stacklevel=2)
    else:
        traj = _resample(traj, mode, max_gap=max_gap)
    traj = validate_trajectory(traj, check_units=False)
    if traj.v is not None and vel == "logged":
        _check_logged_velocity(traj)

    derive_v = traj.v is None or vel == "from-q"
    derive_a = derive_v or traj.a is None or savgol_window is not None
    imu = traj.extras.get(IMU_KEY) is not None
    base_a = (from_pose and imu) or (not from_pose and traj.base_v is not None and traj.base_q is not None
                                     and (traj.base_a is None or savgol_window is not None))
    steps = [name for name, on in (("lowpass", lowpass), ("derivatives", derive_a), ("decimate", decimate > 1),
                                    ("base acceleration", base_a), ("base velocity from the pose", from_pose)) if on]
    if steps and mode == "off":
        now = timing(traj.t, src)
        if not now.is_uniform(jitter_tolerance):
            raise DataError(
                f"{' and '.join(steps)} need(s) uniform sampling but resampling is off and the time stamps are not "
                f"uniform ({now}); use {setting('resample', 'auto')} or a rate in Hz", src)

    if rest not in REST_MODES:
        raise OptionError(f"{setting('rest')} must be one of {', '.join(REST_MODES)}, got {rest!r}")
    sigma_v = None
    if rest == "auto" and not derive_v and len(traj) > 3 * DEFAULT_SAVGOL_WINDOW:
        res = traj.provenance["resolution"]  # as logged (a resampling interpolates between the quanta)
        sigma_v = np.maximum(signal_noise(traj.v), record_floor(res, "v", traj.joint_names))  # before the low-pass
        sigma_q = np.maximum(signal_noise(traj.q), record_floor(res, "q", traj.joint_names))  # colours it (.rest)
    w = int(savgol_window) if savgol_window is not None else default_savgol_window(
        1.0 / float(np.median(np.diff(traj.t))) if len(traj.t) > 1 and np.median(np.diff(traj.t)) > 0 else float("nan"))
    if derive_a and traj.extras.get("contact") is not None:
        fit = _contact_phase_window(traj.extras["contact"])
        if savgol_window is None:
            w = min(w, fit)
        elif w > 2 * fit:
            warnings.warn(f"{src}: the derivative window ({w} samples) spans more than half of the log's median "
                          f"contact phase: the accelerations mix stance and flight (the default here would be {fit} "
                          f"samples; leave {setting('savgol_window')} unset)", DataWarning, stacklevel=2)
    if from_pose:  # from the pose samples as logged, low-passed at the same cut-off, the same derivative window
        traj = base_motion_from_pose(traj.with_(base_a=None) if imu else traj, *pose_samples, cutoff_hz=lowpass,
                                     window=w, keep_base_a=imu,
                                     max_gap_periods=DEFAULT_POSE_MAX_GAP if pose_max_gap is None else pose_max_gap)
    if wrench_frames:
        from .wrench_frames import express_wrenches

        traj = express_wrenches(traj, robot, wrench_frames)
    if lowpass:
        channels = [c for c in lowpass_channels(traj) if not (from_pose and c in ("base_q", "base_v", "base_a"))]
        traj = _lowpass(traj, lowpass, fields=channels)
        traj = traj.with_(provenance={**traj.provenance, "lowpass_hz": float(lowpass), "lowpass": {
            "cutoff_hz": float(lowpass), "filter": "Butterworth order 4, zero-phase (sosfiltfilt)", "channels": channels
            + (["base_q", "base_v", "base_a"] if from_pose else [])}})

    noisy_source = None
    if derive_a and len(traj) > 3 * DEFAULT_SAVGOL_WINDOW:  # the derivative's noise, before the low-pass colours it
        noisy_source = ("q", traj.q) if derive_v else ("v", traj.v)
        noisy_source = (*noisy_source, np.maximum(signal_noise(noisy_source[1]), record_floor(
            traj.provenance.get("resolution"), noisy_source[0], traj.joint_names)))
    if derive_v:
        traj = savgol_derivatives(traj, window=w, polyorder=_POLYORDER)
        how = f"Savitzky-Golay (window {w}, order {_POLYORDER})"
        traj = traj.with_(provenance={
            **traj.provenance, "q": traj.provenance.get("q", "logged") + f", smoothed by {how}",
            "v": f"derived: d/dt q, {how}", "a": f"derived: d²/dt² q, {how}"})
    elif derive_a:
        dt = float(np.median(np.diff(traj.t)))
        sg = with_source(SavitzkyGolay, src, w, _POLYORDER, dt)
        a = with_source(sg.apply, src, traj.v, 1)
        how = f"Savitzky-Golay (window {w}, order {_POLYORDER})"
        traj = traj.with_(a=a, units=note_processing(traj, f"savgol(centred, window={w}, polyorder={_POLYORDER}): a = d/dt of logged v"),
                          provenance={**traj.provenance, "a": f"derived: d/dt of logged v, {how}"})
    if noisy_source is not None:
        traj = _derivative_noise(traj, *noisy_source, w)
    if derive_a and traj.extras.get("contact") is not None:
        traj = _widen_contacts(traj, w // 2)
    if sigma_v is not None:
        traj = zero_at_rest(traj, sigma_v, w, sigma_q)
    if base_a:
        from .imu import base_acceleration  # imported on use: it loads Pinocchio

        traj = base_acceleration(traj, window=w)
        traj = traj.with_(provenance={**traj.provenance, "base_a": "derived (base_acceleration: "
                                      + ("linear part from imu_acc, " if imu else "") + f"Savitzky-Golay window {w})"})
    if decimate and decimate > 1:
        traj = _decimate(traj, decimate)
        traj = traj.with_(provenance={**traj.provenance, "decimate": int(decimate)})
    return traj


#: the default derivative window of a log with contact flags spans at most this share of its median contact phase
CONTACT_PHASE_SHARE = 0.15


def _contact_phase_window(flags: np.ndarray) -> int:
    """The longest derivative window [samples, odd, ≥ 11] that resolves the contact phases of a log:
    :data:`CONTACT_PHASE_SHARE` of its median phase (a run of one contact pattern, the first and last
    runs left out as cut; the median over samples, so that a few milliseconds of bouncing at a
    touchdown do not count as phases). A hopping leg's 0.2 s stance and flight would be smeared by
    the arm default of 0.2 s (the stance force reaching far into the flight); a log with one phase
    keeps any window."""
    f = np.asarray(flags, dtype=bool).reshape(len(flags), -1)
    change = np.flatnonzero(np.any(f[1:] != f[:-1], axis=1)) + 1
    runs = np.sort(np.diff(change))
    if runs.size < 2:
        return 10**9
    median = float(runs[np.searchsorted(np.cumsum(runs), 0.5 * runs.sum())])  # the phase of the median sample
    w = int(max(11, CONTACT_PHASE_SHARE * median))
    return w if w % 2 else w + 1


#: a derived v̇ whose noise std exceeds this share of its RMS is mostly noise (a warning names the joint)
NOISE_DOMINATES = 0.5
#: a joint whose q (or v) spans more than this many noise stds moves (only those are warned about)
MOVING_SIGMAS = 20.0


def _derivative_noise(traj: Trajectory, source: str, x: np.ndarray, sigma: np.ndarray, w: int) -> Trajectory:
    """``provenance["derivative_noise"]``: per joint, the std of the derived v̇ that the noise of ``source`` (q or
    v; σ floored at its quantization, :mod:`.resolution`) implies through the Savitzky–Golay window ``w``,
    σ_a = σ ‖c‖ (c the derivative's coefficients), beside the RMS of v̇; a DataWarning names the joints where
    σ_a is over :data:`NOISE_DOMINATES` of it and that move (their rows then carry mostly noise: a passive slider whose height
    is quantized, differentiated twice over a short window), with the window that would bring it to a quarter."""
    from .savgol import savgol_coeffs

    dt = float(np.median(np.diff(traj.t)))
    order = 2 if source == "q" else 1
    gain = lambda win: float(np.linalg.norm(savgol_coeffs(win, _POLYORDER, deriv=order, delta=dt)))  # noqa: E731
    noise = sigma * gain(w)
    rms = np.sqrt(np.mean(np.asarray(traj.a, dtype=float) ** 2, axis=0))
    names = list(traj.joint_names)
    info = {"window_samples": int(w), "from": source, "noise_std": dict(zip(names, map(float, noise))),
            "rms": dict(zip(names, map(float, rms)))}
    moves = np.ptp(np.asarray(x, dtype=float), axis=0) > MOVING_SIGMAS * sigma  # a held joint's v̇ is noise anyway
    bad = [j for j in range(len(names)) if moves[j] and noise[j] > NOISE_DOMINATES * rms[j] and noise[j] > 0]
    if bad:
        parts = []
        for j in bad:
            wins = [v for v in range(w + 2, min(len(traj), 50 * w), 2) if sigma[j] * gain(v) <= 0.25 * rms[j]]
            hint = f"; a window of {wins[0]} samples would bring it to a quarter" if wins else ""
            parts.append(f"{names[j]} (σ {noise[j]:.3g} against an RMS of {rms[j]:.3g}{hint})")
        warnings.warn(f"{traj.source}: the derived accelerations of {', '.join(parts)} are mostly noise: the "
                      f"{source} noise through the {w}-sample derivative window (the rows of those joints carry "
                      f"it into a fit or a force estimate; {setting('savgol_window')} sets the window)",
                      DataWarning, stacklevel=3)
    return traj.with_(provenance={**traj.provenance, "derivative_noise": info})


def _widen_contacts(traj: Trajectory, half: int) -> Trajectory:
    """Logged contact flags widened by ``half`` samples on each side of every stance: a smoothed
    acceleration within half a derivative window of a touchdown or lift-off carries part of the
    contact force's effect (the impact), so such samples are treated as in contact (a contact
    projection then removes that part, P Jcᵀ = 0)."""
    flags = np.asarray(traj.extras["contact"], dtype=bool)
    if half < 1 or flags.ndim != 2 or not flags.any():
        return traj
    from scipy.ndimage import binary_dilation

    wide = binary_dilation(flags, structure=np.ones((2 * half + 1, 1), dtype=bool))
    return traj.with_(extras={**traj.extras, "contact": wide},
                      provenance={**traj.provenance, "contact": f"logged, each stance widened by {half} samples "
                                  "(half the derivative window: the smoothed accelerations reach into it)"})


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
            raise OptionError(f"{setting('columns')}: '{part}' is not FIELD=SPEC (e.g. 'q=0:7;tau=14:21')")
        key, val = (s.strip() for s in part.split("=", 1))
        out[key] = val.split("|") if "|" in val else val
    return out


PREPROCESSING_KEYS = ("columns", "gains", "rate", "resample", "lowpass", "savgol_window", "velocity", "max_gap",
                      "rest", "time_unit", "base_velocity", "pose_max_gap", "wrench_frames", "angle_unit")
"""Options a model remembers in result.json (settings.preprocessing) and predict/estimate-force reuse.
The trim window and decimation belong to one log and are recorded but not reused."""


def check_preprocessing(rate, lowpass, savgol_window, decimate) -> None:
    """OptionError for preprocessing options no log can use (zero, negative, NaN, absurd)."""
    from .timebase import MAX_RATE, MIN_RATE

    if rate is not None and not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
        raise OptionError(f"{setting('rate')} must be a sample rate in [{MIN_RATE:g}, {MAX_RATE:g}] Hz, got {rate!r}")
    if lowpass is not None and not (math.isfinite(lowpass) and lowpass > 0):
        raise OptionError(f"{setting('lowpass')} must be a cut-off frequency > 0 Hz, got {lowpass!r}")
    if savgol_window is not None and (savgol_window < 5 or savgol_window % 2 == 0):
        raise OptionError(f"{setting('savgol_window')} must be an odd number of samples >= 5, got {savgol_window!r}")
    if decimate is not None and decimate < 1:
        raise OptionError(f"{setting('decimate')} must be an integer >= 1, got {decimate!r}")


def with_imu_frame(traj: Trajectory, robot, frame: str, savgol_window: int | None = None) -> Trajectory:
    """``traj`` with base_a rebuilt from its accelerometer ('imu_acc') read in model frame
    ``frame`` (:func:`~sensorless.data.imu.base_acceleration`); the derivative window is
    ``savgol_window``, else the default at the log's rate (as for v̇)."""
    from .imu import base_acceleration

    return base_acceleration(traj, window=savgol_window or default_savgol_window(1.0 / traj.dt), robot=robot,
                             imu_frame=frame)


def load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, *, gains=None, trim=None,
             resample="auto", velocity="logged", max_gap=None, outliers: str = "error", rest=None, time_unit=None,
             base_velocity=None, pose_max_gap=None, wrench_frames=None,
             max_memory=None, allow_external=None, skip_bad=None, accept_implausible_gains=None, skip_bad_rows=None,
             angle_unit=None):
    """Read, validate and preprocess one log (:func:`sensorless.data.prepare`).

    ``trim`` (a window, or a :class:`~sensorless.data.LogTrims` holding this log's) is cut and
    ``skip_bad_rows`` drops a corrupt prefix/suffix while reading, before the time axis is checked
    (:func:`~sensorless.data.validate_trajectory`).

    The one preprocessing function of both the local path (``sensorless.cli.common.load_logs``) and the Dask
    workers (:class:`sensorless.regressor.distributed.LogReader`), so both see the same samples.
    ``outliers`` ("error" | "drop" | "keep") is applied to the raw log; a log that lost samples
    that way is resampled onto its uniform grid even with ``resample="off"``. ``max_memory``,
    ``allow_external``, ``skip_bad``, ``accept_implausible_gains``, ``skip_bad_rows`` and ``angle_unit``
    ("deg": joint angles logged in degrees, :mod:`~sensorless.data.angles`):
    :func:`sensorless.data.limits.read_options`.
    """
    if isinstance(trim, LogTrims):
        trim = trim.window_for(path)
    with read_options(max_memory=max_memory, allow_external=allow_external, skip_bad=skip_bad,
                      accept_implausible_gains=accept_implausible_gains, skip_bad_rows=skip_bad_rows,
                      angle_unit=angle_unit):
        return _load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, gains, trim, resample,
                         velocity, max_gap, outliers, rest, time_unit, base_velocity, pose_max_gap, wrench_frames)


def _load_log(path, robot, columns, rate, lowpass, savgol_window, decimate, gains, trim, resample, velocity, max_gap,
              outliers, rest, time_unit, base_velocity, pose_max_gap, wrench_frames):
    from .outliers import OUTLIER_MODES
    from .readers import read_trajectory

    check_preprocessing(rate, lowpass, savgol_window, decimate)
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"{setting('outliers')} must be one of {', '.join(OUTLIER_MODES)}, got {outliers!r}")
    if pose_max_gap is not None and not (math.isfinite(pose_max_gap) and pose_max_gap > 1):
        raise OptionError(f"{setting('pose_max_gap')} must be a number of median pose periods > 1, got {pose_max_gap!r}")
    mode = parse_resample(resample)
    cols = parse_columns(columns) if isinstance(columns, str) else columns
    if isinstance(gains, str) and gains.strip().lower() in ("off", "none"):
        gains = None
    traj = read_trajectory(path, columns=cols, rate=rate, robot=robot, gains=gains, time_unit=time_unit,
                           allow_duplicate_times=mode != "off", outliers=outliers, trim=trim)
    check_integrity(traj)  # shuffled torque rows, periodic zero samples: before any filter hides them
    dropped = "outlier" in traj.units.get("processing", "")
    out = prepare(traj, resample="auto" if dropped and mode == "off" else mode, lowpass=lowpass,
                  savgol_window=savgol_window, velocity=velocity or "logged", decimate=decimate or 1,
                  max_gap=DEFAULT_MAX_GAP if max_gap is None else max_gap, rest=rest or "auto",
                  base_velocity=base_velocity or "auto", pose_max_gap=pose_max_gap, robot=robot,
                  wrench_frames=wrench_frames or None)
    if not current_options().get("accept_implausible_gains"):
        check_gain_plausibility(out, robot)  # τ = K·i against the model's torque scale, per joint
    return out

"""Collision monitoring of one log, as a library call (``sensorless monitor`` parses its options into it).

    rest mask: |v| ≤ δ and q within its noise, for ≥ the observer's settling time (v := 0 there)  →  observer r ≈ L(s)[τ_ext]
    →  warm-up blanked
    →  quiet-window statistics per joint and state
    →  per sample: at rest (|v| ≤ δ), the static-friction dead zone and the holding level
       (:mod:`.static_band`); in motion, k σ around the quiet bias  →  contact intervals.

Signs follow ``estimate-force``: the returned τ_ext = τ_measured − τ_model (minus the
observer's r, the torque acting on the robot), so that τ_ext = Jᵀ F with F the force the
robot exerts on its environment.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..data.trims import TrimWindow
from ..data.trajectory import Trajectory
from ..errors import DataError
from .collision import ContactInterval, check_quiet_window, observer_warmup, quiet_mask, runs
from .momentum import MomentumDynamics, MomentumObserver, ObserverResult
from .monitored import MonitoredTorque, monitored_rows, monitored_torque
from .static_band import (STATUS, MonitorTrace, RestAwareThresholds, StaticFriction, classify_at_rest,
                          laws_static_friction, model_static_friction, rest_aware_thresholds, rest_intervals, rest_speeds)

__all__ = ["MonitorResult", "MonitorSettings", "monitor_log", "still_mask"]


def still_mask(t: np.ndarray, v: np.ndarray, speeds: np.ndarray, blip: float, hold: float = 0.0,
               q: np.ndarray | None = None, q_range: np.ndarray | None = None) -> np.ndarray:
    """(N, n) bool: the joint is still. |v_j| ≤ δ_j, with runs above δ_j shorter than ``blip`` s
    between two still samples counted as still (a noise spike of v is not a motion); with ``q``,
    q_j (a moving average over a tenth of the window) must also stay within ``q_range`` over the
    centred ``hold`` window (a joint creeping below the velocity noise moves); still runs shorter than ``hold`` s are dropped (a velocity
    reversal is not a rest)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d

    t = np.asarray(t, float)
    still = np.abs(np.asarray(v, float)) <= np.asarray(speeds, float)[None, :]
    eps = 1e-12 * max(abs(t[0]), abs(t[-1]), 1.0)
    for j in range(still.shape[1]):
        for a, b in runs(~still[:, j]):
            if a > 0 and b < len(t) - 1 and t[b + 1] - t[a - 1] <= blip + eps:
                still[a : b + 1, j] = True
    if q is not None and q_range is not None and len(t) > 1:
        w = max(int(round(hold / float(np.median(np.diff(t))))) + 1, 1)
        q = uniform_filter1d(np.asarray(q, float), max(w // 10, 1), axis=0, mode="nearest")  # ≥ 3× less noise
        span = maximum_filter1d(q, w, axis=0, mode="nearest") - minimum_filter1d(q, w, axis=0, mode="nearest")
        still &= span <= np.asarray(q_range, float)[None, :]
    for j in range(still.shape[1]):
        for a, b in runs(still[:, j]):
            if t[b] - t[a] < hold - eps:
                still[a : b + 1, j] = False
    return still


@dataclass(frozen=True)
class MonitorSettings:
    """Options of :func:`monitor_log` (the defaults are the CLI's).

    ``quiet``: contact-free window, ``--trim`` syntax; ``k`` or ``false_alarm_rate`` [1/min];
    observer ``gain`` K [1/s] and ``order``; ``static_friction``: "model", "off" or f_s per
    monitored joint [N·m]; ``static_margin``: the band is ±f_s (1 + margin); ``rest_speed``:
    "auto" or δ [rad/s]; ``warmup``: None (until the observer has converged) or seconds; ``merge_gap`` [s]:
    contacts closer than this, or than the observer's settling time, are one (the output of a contact that
    ended decays through L(s) for that long: a re-crossing then is its tail, not a new contact)."""

    quiet: str = "0:1"
    k: float | None = None
    false_alarm_rate: float = 1.0
    gain: float = 50.0
    order: int = 1
    static_friction: "str | tuple[float, ...]" = "model"
    static_margin: float = 0.25
    rest_speed: "str | float" = "auto"
    warmup: float | None = None
    min_duration: float = 0.02
    merge_gap: float = 0.05

    def check(self, n: int) -> None:
        """DataError naming the setting when one is out of range."""
        if self.k is not None and not self.k > 0:
            raise DataError(f"k must be > 0, got {self.k}")
        if not (np.isfinite(self.static_margin) and self.static_margin >= 0):
            raise DataError(f"static_margin must be ≥ 0, got {self.static_margin}")
        if self.warmup is not None and not (np.isfinite(self.warmup) and self.warmup >= 0):
            raise DataError(f"warmup must be ≥ 0 seconds, got {self.warmup}")
        if isinstance(self.static_friction, str):
            if self.static_friction not in ("model", "off"):
                raise DataError(f"static_friction must be 'model', 'off' or values, got {self.static_friction!r}")
        elif len(self.static_friction) != n or not all(np.isfinite(v) and v >= 0 for v in self.static_friction):
            raise DataError(f"static_friction needs {n} values ≥ 0 N·m, got {self.static_friction!r}")
        if not isinstance(self.rest_speed, str) and not (np.isfinite(self.rest_speed) and self.rest_speed >= 0):
            raise DataError(f"rest_speed must be 'auto' or ≥ 0 rad/s, got {self.rest_speed}")
        TrimWindow.parse(self.quiet)


@dataclass
class MonitorResult:
    """Everything :func:`monitor_log` decided (``trace``: per-sample τ_ext, NaN during the warm-up,
    status and holding level)."""

    t: np.ndarray
    names: list[str]
    raw: np.ndarray  # τ_ext before any bias is removed (N, n)
    observer: ObserverResult
    trace: MonitorTrace
    thresholds: RestAwareThresholds
    contacts: list[ContactInterval]
    static_band: list[ContactInterval]
    contact: np.ndarray  # (N,) inside a reported contact interval
    quiet: np.ndarray  # (N,) samples the statistics came from
    rest_speed: np.ndarray
    settings: dict = field(default_factory=dict)
    monitored: MonitoredTorque | None = None  # rows and contact projector (None: a friction-only model)

    @property
    def tau_ext(self) -> np.ndarray:
        return self.trace.tau_ext



def monitor_log(dyn: MomentumDynamics, traj: Trajectory, settings: MonitorSettings = MonitorSettings(), *,
                static: StaticFriction | None = None, savgol_window: int | None = None) -> MonitorResult:
    """Monitor ``traj`` with the identified model ``dyn`` (module docstring). ``static``: f_s per
    joint when ``settings.static_friction == "model"`` (default: :func:`model_static_friction`
    of ``dyn``); ``savgol_window``: the derivative window the log's v came from, if derived."""
    s = settings
    names = monitored_rows(dyn)[0]  # actuated and passive joints; with contacts every row, projected
    s.check(len(names))
    window = TrimWindow.parse(s.quiet)
    logged = list(traj.joint_names)
    jr = [k for k, n in enumerate(names) if n in logged]  # rows that are logged joints (not a floating base's)
    cols = [logged.index(names[k]) for k in jr]
    auto_speeds, q_range = np.full(len(names), np.nan), np.full(len(names), np.nan)
    auto_speeds[jr], q_range[jr], speed_src = rest_speeds(traj, [names[k] for k in jr], savgol_window)
    if isinstance(s.rest_speed, str):
        speeds = auto_speeds
    else:
        speeds, speed_src = np.full(len(names), float(s.rest_speed)), "given"
    dt = float(np.median(np.diff(traj.t)))
    settle = observer_warmup(s.gain, s.order, dt)
    warm = settle if s.warmup is None else float(s.warmup)
    rest = np.zeros((len(traj.t), len(names)), bool)  # a base row is never "at rest" (no static friction there)
    rest[:, jr] = still_mask(traj.t, traj.v[:, cols], speeds[jr], s.min_duration, settle, traj.q[:, cols], q_range[jr])
    if s.static_friction == "off":
        rest[:] = False  # one threshold everywhere, as in motion
    v = traj.v.copy()
    v[:, cols] = np.where(rest[:, jr], 0.0, v[:, cols])  # at rest the friction is the band, not the sliding law
    res = MomentumObserver(dyn, gain=s.gain, order=s.order).run(traj.with_(v=v))
    monitored = monitored_torque(dyn, res.r, traj) if hasattr(dyn, "structure") else None
    raw = -res.tau_ext if monitored is None else monitored.tau_ext
    t = np.asarray(traj.t, float)
    if s.static_friction == "model":
        static = static or (model_static_friction(dyn.structure, dyn.params, names) if hasattr(dyn, "structure")
                            else laws_static_friction(dyn.model.laws_, names))  # a friction-only model
    elif s.static_friction == "off":
        static = StaticFriction(names, np.zeros(len(names)), ["off"] * len(names))
    else:
        static = StaticFriction(names, np.asarray(s.static_friction, float), ["given"] * len(names))
    mask = quiet_mask(t, window, traj.source, exclude=t < t[0] + warm)
    check_quiet_window(raw, t, mask, names, s.quiet, usable=t >= t[0] + warm, source=traj.source)
    th = rest_aware_thresholds(raw, rest, mask, static, k=s.k, false_alarm_rate=None if s.k is not None else
                               s.false_alarm_rate, dt=dt, margin=s.static_margin)
    trace = classify_at_rest(raw, t, rest, th, quiet=mask, warmup=warm, settle=settle)
    merge = max(s.merge_gap, settle)  # a re-crossing while r still decays through L(s) is the same contact
    flag, contacts, band = rest_intervals(trace, t, raw, th, min_duration=s.min_duration, merge_gap=merge)
    lo, hi = window.bounds(t)
    used = {**asdict(s), "static_friction": s.static_friction if isinstance(s.static_friction, str)
            else list(s.static_friction)}
    used.update({
        "quiet_window_s": [float(max(lo, t[0]) - t[0]), float(min(hi, t[-1]) - t[0])],
        "quiet_window_stamps": [float(max(lo, t[0])), float(min(hi, t[-1]))], "quiet_samples": int(mask.sum()),
        "merge_gap_s": merge, "warmup_s": warm, "warmup_source": "observer convergence (step response within 1e-3)" if s.warmup is None
        else "given", "settle_s": settle, "k_used": th.k, "rest_speed_per_joint": dict(zip(names, speeds.tolist())),
        "rest_position_range": dict(zip(names, q_range.tolist())),
        "rest_speed_source": speed_src, "status_codes": list(STATUS),
    })
    return MonitorResult(t, names, raw, res, trace, th, contacts, band, flag, mask, speeds, used, monitored)

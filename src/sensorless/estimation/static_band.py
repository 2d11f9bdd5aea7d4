"""Contact decisions on a joint at rest: the static-friction dead zone and the holding level.

At rest (v = v̇ = 0) the equation of joint j reduces to

    0 = τ + τ_ext − g(q) − o − f,     f ∈ [−f_s, f_s]   (static friction holds whatever is needed),

and the momentum observer, run with v = 0 where |v| ≤ δ for at least its settling time (the
sliding law does not apply at rest, and tanh(noise/ε) would chatter by up to f_c; a brief
|v| ≤ δ is a velocity reversal, not a rest), returns r = τ_ext − f + e, with e
the model error at the pose. So at rest

    r ∈ τ_ext + [e − f_s, e + f_s]:

τ_ext = 0 explains any r in the band B = [c − f_s, c + f_s] (c = ê): an external torque
inside it is *indistinguishable from static friction*; only r outside B proves a contact,
and then |τ_ext| ≥ dist(r, B) (``band_excess``). A position-controlled arm held still makes
this the common case: a push that moves a joint ends with the joint stuck wherever its
position loop and friction balance, so its holding torque, and r, settle at a new level
anywhere in B.

**Band centre.** Moving quiet samples (friction modelled while sliding) give e ≈ their median
b_m. A joint at rest throughout the quiet window only shows its level b = e − f₀, i.e.
e ∈ [b − f_s, b + f_s]; the estimate nearest the model is ê = clip(0, b − f_s, b + f_s). Either
way c = clip(b_m or 0, b − f_s, b + f_s) keeps the quiet level inside B.

**Holding level.** Per rest segment of joint j (a run of |v_j| ≤ δ_j with q_j within its noise;
:func:`~sensorless.estimation.monitoring.still_mask`), the joint counts as at
rest once it has been still for ``settle`` (the observer's convergence time: until then r still
carries the motion through L(s): the reported torque is r − b_m as in motion). The level h is then the
mean of r over the settled samples so far (in the segment that holds the quiet window, or
starts the log: the quiet-window mean), restarted when r has stayed more than kσ_r away
from it for ``settle`` (a joint creeping below δ moves its stick torque too), and clipped to
B. The reported external torque at rest is r − h: the change since the joint settled (noise
once a push has ended, whatever new stick torque it left), never the stick torque itself.

**Per sample and joint** (``STATUS``):

* at rest, and for ``settle`` after leaving it (breakaway: the friction passes from the
  stick value to the sliding law, and r still carries the rest): ``contact`` if
  |r − c| > f_s + kσ_r; else ``static_band`` if the reported torque (r − h at a settled rest,
  r − the last h while breaking away, r − b_m after a stop) exceeds kσ: a change, inside the
  band, that friction explains; else ``quiet``. The first
  ``settle`` of a rest, where r still carries the motion, lies between the sliding residual
  and the new stick level, both inside the band, so the same test holds there;
* moving: ``contact`` if |r − b_m| > kσ_m (the identified friction applies); else ``quiet``;
* ``warmup`` before the observer has converged (never a contact).

f_s per joint is the model's static friction (:func:`model_static_friction`: fc + (fs − fc) of
the Stribeck term, or fc), or, where the model has none, from the quiet window (the range
of |r − b_m| in motion, or |b| at rest: a lower bound) and labelled so. The band's
half-width is f_s (1 + margin), margin 0.25 by default: f_s identified from sliding data is
the friction curve extrapolated to v = 0, while breakaway friction varies with dwell time,
temperature and position by tens of percent, and ê carries the model's error at the pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from .collision import ContactInterval, contact_intervals, runs, threshold_multiplier

__all__ = ["STATUS", "MonitorTrace", "RestAwareThresholds", "StaticFriction", "classify_at_rest", "laws_static_friction", "model_static_friction",
           "rest_aware_thresholds", "rest_intervals", "rest_speeds"]

STATUS = ("quiet", "contact", "static_band", "warmup")
QUIET, CONTACT, STATIC_BAND, WARMUP = range(4)
MIN_SAMPLES = 20


@dataclass
class StaticFriction:
    """Static friction f_s per joint [N·m] (NaN: unknown) and where each value comes from."""

    names: list[str]
    values: np.ndarray
    sources: list[str]


def model_static_friction(structure, params: np.ndarray, names) -> StaticFriction:
    """f_s of an identified model per monitored joint/coordinate: max(fc, fc + (fs − fc)) of its
    Coulomb and Stribeck terms; for a transmission Σ_d |g_d| f_s,d over the drives; NaN where
    the model has no Coulomb term."""
    params = np.asarray(params, float)
    names = list(names)
    vals, src = np.full(len(names), np.nan), ["none"] * len(names)
    drives = getattr(structure, "drives", ())
    if drives:
        values = structure.drive_values(params)
        coords = list(getattr(structure, "coordinates", names))
        acc = np.zeros(len(coords))
        has = np.zeros(len(coords), bool)
        for d in drives:
            dv = values[d.name]
            if "fc" in dv:
                fs = max(dv["fc"], dv["fc"] + dv.get("stribeck", 0.0))
                acc += np.abs(d.g) * max(fs, 0.0)
                has |= np.abs(d.g) > 0
        for k, n in enumerate(names):
            if n in coords and has[coords.index(n)]:
                vals[k], src[k] = acc[coords.index(n)], "model: drive Coulomb/Stribeck terms"
        return StaticFriction(names, vals, src)
    for k, n in enumerate(names):
        terms = structure.terms_of(n) if n in structure.robot.actuated_joints else ()
        if "fc" not in terms:
            continue
        fc = params[structure.joint_term_index(n, "fc")]  # + the presliding amplitude: its state is ±1 sliding
        fc += params[structure.joint_term_index(n, "presliding")] if "presliding" in terms else 0.0
        st = params[structure.joint_term_index(n, "stribeck")] if "stribeck" in terms else 0.0
        vals[k] = max(fc, fc + st, 0.0)
        src[k] = "model: fc + Stribeck (fs − fc)" if "stribeck" in terms else "model: Coulomb fc"
    return StaticFriction(names, vals, src)


def laws_static_friction(laws: dict, names) -> StaticFriction:
    """f_s = max(fc, fc + (fs − fc)) per joint of a friction-only model's laws ({joint: law with
    ``coef``}, :mod:`sensorless.identification.friction_model`), as :func:`model_static_friction`."""
    names = list(names)
    coefs = [laws[n].coef for n in names]
    vals = np.array([max(c.get("fc", np.nan), c.get("fc", np.nan) + c.get("stribeck", 0.0)) for c in coefs])
    return StaticFriction(names, vals, ["model: friction law fc + Stribeck"] * len(names))


@dataclass
class RestAwareThresholds:
    """Per-joint statistics of a quiet window split by state (module docstring)."""

    names: list[str]
    k: float
    sigma_rest: np.ndarray
    sigma_move: np.ndarray
    bias_rest: np.ndarray  # quiet-window mean of r at rest (NaN: the joint moved throughout)
    bias_move: np.ndarray  # quiet-window median of r in motion (the band centre where none)
    centre: np.ndarray
    band: np.ndarray  # f_s used as the half-width of the dead zone (0: off)
    band_source: list[str]
    samples_rest: np.ndarray
    samples_move: np.ndarray

    def to_dict(self) -> dict:
        f = lambda a: [float(x) if np.isfinite(x) else None for x in a]  # noqa: E731
        return {"names": list(self.names), "k": self.k, "sigma_rest": f(self.sigma_rest), "sigma_moving": f(self.sigma_move),
                "threshold_rest": f(self.k * self.sigma_rest), "threshold_moving": f(self.k * self.sigma_move),
                "bias_rest": f(self.bias_rest), "bias_moving": f(self.bias_move), "band_centre": f(self.centre),
                "static_friction": f(self.band), "static_friction_source": list(self.band_source),
                "quiet_samples_rest": self.samples_rest.tolist(), "quiet_samples_moving": self.samples_move.tolist()}


def rest_aware_thresholds(r: np.ndarray, rest: np.ndarray, quiet: np.ndarray, static: StaticFriction, *,
                          k: float | None = None, false_alarm_rate: float | None = None,
                          dt: float | None = None, margin: float = 0.25) -> RestAwareThresholds:
    """Quiet-window statistics per joint and state, the band centre and half-width (module docstring).

    ``r`` (N, n) observer output, ``rest`` (N, n) bool per joint, ``quiet`` (N,) bool; k given or
    from a false-alarm rate λ [1/min] (Gaussian, per-sample p = λ dt / (60 n), k = Φ⁻¹(1 − p/2)).
    The half-width is f_s (1 + ``margin``) (module docstring)."""
    if not (np.isfinite(margin) and margin >= 0):
        raise DataError(f"the static-friction margin must be ≥ 0, got {margin}")
    r, rest, quiet = np.asarray(r, float), np.asarray(rest, bool), np.asarray(quiet, bool)
    n = r.shape[1]
    if quiet.sum() < MIN_SAMPLES:
        raise DataError(f"the quiet segment has {int(quiet.sum())} samples; need ≥ {MIN_SAMPLES}")
    k = threshold_multiplier(k, false_alarm_rate, dt, n)
    nan = np.full(n, np.nan)
    s_r, s_m, b_r, b_m, c, band = nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy()
    n_r, n_m = np.zeros(n, int), np.zeros(n, int)
    src = list(static.sources)
    for j in range(n):
        xr, xm = r[quiet & rest[:, j], j], r[quiet & ~rest[:, j], j]
        n_r[j], n_m[j] = xr.size, xm.size
        if xr.size >= MIN_SAMPLES:
            b_r[j], s_r[j] = xr.mean(), xr.std()
        if xm.size >= MIN_SAMPLES:
            b_m[j], s_m[j] = np.median(xm), xm.std()
        if not np.isfinite(s_r[j]):
            s_r[j] = s_m[j] if np.isfinite(s_m[j]) else np.concatenate([xr, xm]).std()
        if not np.isfinite(s_m[j]):
            s_m[j] = s_r[j]
        fs = static.values[j]
        if not np.isfinite(fs):  # the model has no static friction: what the quiet window shows, labelled
            if np.isfinite(b_m[j]):
                fs, src[j] = float(np.max(np.abs(xm - b_m[j]))), "quiet window: range of r in motion (the model has no Coulomb term)"
            elif np.isfinite(b_r[j]):
                fs, src[j] = abs(b_r[j]), "quiet window: |holding level| at rest, a lower bound (the model has no Coulomb term)"
            else:
                fs, src[j] = 0.0, "none: too few quiet samples"
        band[j] = max(fs, 0.0) * (1.0 + margin)
        c0 = b_m[j] if np.isfinite(b_m[j]) else 0.0
        c[j] = np.clip(c0, b_r[j] - band[j], b_r[j] + band[j]) if np.isfinite(b_r[j]) else c0
        if not np.isfinite(b_m[j]):
            b_m[j] = c[j]
    tiny = 1e-12
    return RestAwareThresholds(list(static.names), float(k), np.maximum(s_r, tiny), np.maximum(s_m, tiny), b_r, b_m, c,
                               band, src, n_r, n_m)


@dataclass
class MonitorTrace:
    """Per-sample decisions: reported τ_ext (N, n; NaN in the warm-up), holding level h (NaN when not at rest), status
    codes (N, n) into :data:`STATUS`, the settled-rest mask, the contact flag (N,) and ``near`` (N, n): at rest or
    breaking away, where the static-friction band applies."""

    tau_ext: np.ndarray
    holding: np.ndarray
    status: np.ndarray
    rest: np.ndarray
    contact: np.ndarray
    near: np.ndarray | None = None

    def status_names(self) -> np.ndarray:
        return np.asarray(STATUS)[self.status]

    def contact_bounds(self, r: np.ndarray, th: "RestAwareThresholds") -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (N, n): the reported τ_ext outside which a sample is a contact. With the offset
        o = r − τ_ext (the holding level or the moving bias): b_m ± kσ_m − o in motion (= ±kσ_m),
        c ± (f_s + kσ_r) − o at rest or breaking away (the static-friction dead zone); NaN in the warm-up."""
        off = np.asarray(r, float) - self.tau_ext
        near = np.zeros_like(self.rest) if self.near is None else self.near
        centre = np.where(near, th.centre, th.bias_move)
        half = np.where(near, th.band + th.k * th.sigma_rest, th.k * th.sigma_move)
        return centre - half - off, centre + half - off


def classify_at_rest(r: np.ndarray, t: np.ndarray, rest: np.ndarray, th: RestAwareThresholds, *, quiet: np.ndarray,
                     warmup: float, settle: float) -> MonitorTrace:
    """Status, holding level and reported external torque per sample and joint (module docstring)."""
    r, t, rest = np.asarray(r, float), np.asarray(t, float), np.asarray(rest, bool)
    quiet = np.asarray(quiet, bool)
    N, n = r.shape
    h = np.full((N, n), np.nan)
    settled = np.zeros((N, n), bool)
    near = rest.copy()  # at rest, or leaving it for less than ``settle``: friction in the band
    ref = np.broadcast_to(th.bias_move, (N, n)).copy()
    for j in range(n):
        lo, hi = th.centre[j] - th.band[j], th.centre[j] + th.band[j]
        thr = th.k * th.sigma_rest[j]
        leaving = []
        for s, e in runs(rest[:, j]):
            leaving.append((e + 1, int(np.searchsorted(t, t[e] + settle, side="right"))))
            near[e : leaving[-1][1], j] = True
            if np.isfinite(th.bias_rest[j]) and (s == 0 or quiet[s : e + 1].any()):
                k0, h0 = s, th.bias_rest[j]  # the quiet window's rest: its bias is the holding level
            else:
                k0, h0 = s + int(np.searchsorted(t[s : e + 1], t[s] + settle)), None
            if k0 <= e:
                settled[k0 : e + 1, j] = True
                h[k0 : e + 1, j] = np.clip(_holding_level(r[k0 : e + 1, j], t[k0 : e + 1], h0, thr, settle), lo, hi)
        for a, b in leaving:  # breaking away, r still holds the rest: report against the last holding level
            if a < b and np.isfinite(h[a - 1, j]):
                ref[a:b, j] = h[a - 1, j]
    tau = np.where(settled, r - h, r - ref)
    out_band = np.abs(r - th.centre) - th.band > th.k * th.sigma_rest
    moving_over = np.abs(r - th.bias_move) > th.k * th.sigma_move
    changed = np.where(settled, np.abs(r - h) > th.k * th.sigma_rest, np.abs(r - ref) > th.k * th.sigma_move)
    status = np.full((N, n), QUIET, dtype=np.int8)
    status[near & changed] = STATIC_BAND
    status[near & out_band] = CONTACT
    status[~near & moving_over] = CONTACT
    rest = settled
    warm = t < t[0] + warmup
    status[warm] = WARMUP
    tau[warm] = np.nan  # the observer has not converged: no estimate
    return MonitorTrace(tau, h, status, rest, (status == CONTACT).any(axis=1), near)


def _holding_level(x: np.ndarray, t: np.ndarray, h0: float | None, thr: float, settle: float) -> np.ndarray:
    """Piecewise-constant level of a settled rest segment: the running mean of x (or ``h0``), restarted
    when x has stayed more than ``thr`` away from it for ``settle`` s (the stick torque moved)."""
    out = np.empty_like(x)
    total, count, fixed = 0.0, 0, h0
    away = None
    for i, xi in enumerate(x):
        level = fixed if fixed is not None else (total / count if count else xi)
        if abs(xi - level) > thr and (fixed is not None or count):
            away = i if away is None else away
            if t[i] - t[away] >= settle:
                total, count, fixed, away = xi, 1, None, None
                level = xi
        else:
            away = None
            if fixed is None:
                total, count = total + xi, count + 1
                level = total / count
        out[i] = level
    return out


def rest_intervals(trace: MonitorTrace, t: np.ndarray, r: np.ndarray, th: RestAwareThresholds, *,
                   min_duration: float = 0.0, merge_gap: float = 0.0) -> tuple[np.ndarray, list[ContactInterval],
                                                                            list[ContactInterval]]:
    """(contact flag, contact intervals, static-band intervals). Contact intervals carry, per
    crossed joint, its state at the peak and, at rest, the excess over the band (a lower bound
    of |τ_ext|); static-band intervals are runs where some joint changed inside its band and no
    joint is in contact (an external torque there is indistinguishable from static friction)."""
    t, r = np.asarray(t, float), np.asarray(r, float)
    over = trace.status == CONTACT
    flag, contacts = contact_intervals(over, t, trace.tau_ext, th.names, min_duration=min_duration, merge_gap=merge_gap)
    excess = np.abs(r - th.centre) - th.band
    for iv in contacts:
        sl = slice(iv.start_index, iv.end_index + 1)
        for j, name in enumerate(th.names):
            if name not in iv.joints:
                continue
            hit = np.flatnonzero(over[sl, j])
            at = iv.start_index + hit[np.argmax(np.abs(trace.tau_ext[sl, j][hit]))]
            iv.state[name] = "rest" if trace.rest[at, j] else "moving"
            if trace.rest[at, j]:
                iv.band_excess[name] = float(np.max(excess[sl, j][trace.rest[sl, j] & over[sl, j]]))
    band = (trace.status == STATIC_BAND) & ~flag[:, None]
    _, inside = contact_intervals(band, t, trace.tau_ext, th.names, min_duration=min_duration, merge_gap=merge_gap)
    for iv in inside:
        iv.state = {name: "rest" for name in iv.joints}
    return flag, contacts, inside


def rest_speeds(traj, names, window: int | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """(δ, q range, source) per joint of ``names``: at rest |v| ≤ δ [rad/s] and q stays within the
    range [rad]. δ is the log's own rest detection when preprocessing ran it (5 σ_v), else
    ``REST_SIGMAS`` times the velocity noise (of the logged v, or of a Savitzky–Golay v of
    ``window`` samples from q; every σ at least the signal's quantization noise); the range is
    ``RANGE_SIGMAS`` σ_q, at least two encoder steps (:func:`~sensorless.data.resolution.channel_resolution`)."""
    from ..data.resolution import channel_resolution
    from ..data.rest import RANGE_SIGMAS, REST_SIGMAS, signal_noise
    from ..data.savgol import savgol_coeffs

    joints = list(traj.joint_names)
    missing = [n for n in names if n not in joints]
    if missing:
        raise DataError(f"the log has no joint(s) {missing}; it has {joints}", traj.source)
    idx = [joints.index(n) for n in names]
    q = np.asarray(traj.q, float)[:, idx]
    rest = traj.provenance.get("rest") or {}
    step = np.array([channel_resolution(c).step for c in q.T])  # the encoder's quantum (0: none)
    sigma_q = (np.array([rest["position_noise"][n] for n in names], float) if rest.get("position_noise")
               else signal_noise(q))
    q_range = np.maximum(RANGE_SIGMAS * sigma_q, 2.0 * step)
    if rest.get("rest_velocity"):
        return (np.array([rest["rest_velocity"][n] for n in names], float), q_range,
                f"the log's rest detection ({REST_SIGMAS:g} σ of the logged velocity noise)")
    if str(traj.provenance.get("v", "logged")).startswith("derived"):
        dt = float(np.median(np.diff(traj.t)))
        w = int(window) if window else 11
        w += 1 - w % 2
        gain = np.linalg.norm(savgol_coeffs(w, 3, deriv=1, delta=dt))
        return (REST_SIGMAS * signal_noise(q) * gain, q_range,
                f"{REST_SIGMAS:g} σ of the Savitzky–Golay velocity (window {w}) from the position noise")
    return REST_SIGMAS * signal_noise(traj.v[:, idx]), q_range, f"{REST_SIGMAS:g} σ of the logged velocity noise"

"""Base pose, twist and acceleration from motion capture that holds, drops and wraps.

Mocap base poses arrive with repeated samples (the tracker holds its last value when it
loses the markers), NaN gaps, duplicate or jittery stamps, Euler yaw that wraps at ±π
and quaternions whose sign flips. :func:`clean_base_pose` turns them into Pinocchio's
floating-base convention on a uniform (or given) time grid:

1. **clean**: non-finite samples, held samples (position and rotation identical to the
   previous sample's, within ``hold_tol``) and duplicate stamps are dropped; a run of identical
   poses after which the base moves by less than a tenth of its median sample-to-sample step is
   a base at rest, kept as measured (a tracker that held its value jumps). At the ends of the
   stream they are not gaps but samples without a pose: a leading run of repeats keeps its last
   sample, a trailing run its first, and what lies outside is clipped (counted in ``report``,
   a :class:`~sensorless.errors.DataWarning` when requested times fall there). Inside, a gap
   longer than ``max_gap_periods`` median periods of the kept samples (default 10: a few
   dropped frames and ±10 % jitter pass) is an error naming where it is.
2. **interpolate**: positions by a cubic spline (``scipy.interpolate.make_interp_spline``),
   orientations by ``scipy.spatial.transform.Slerp`` (shortest arc: yaw wrap and the
   quaternion sign do not matter; :func:`~.filtering.sign_continuous` before filtering).
3. **low-pass**: zero-phase Butterworth (:func:`~.filtering.butter_lowpass`) on p and on
   the sign-continuous quaternion, renormalised.
4. **differentiate**: Savitzky–Golay (:class:`~.filtering.SavitzkyGolay`) ṗ, p̈, q̇, q̈, then
   the LOCAL twist and its derivative (Pinocchio's free-flyer)::

       v = Rᵀ ṗ,   ω = 2 vec(q̄ ⊗ q̇),   a_lin = Rᵀ p̈ − ω × v,   ω̇ = 2 vec(q̄ ⊗ q̈)

   (d/dt(q̄ ⊗ q̇) = q̄ ⊗ q̈ + |q̇|², whose vector part is that of q̄ ⊗ q̈).

:func:`with_base_pose` fills ``base_q``, ``base_v``, ``base_a`` of a joint log from a
mocap stream on another clock; :func:`base_motion_from_pose` does it for a log whose own
``base_q`` columns are the mocap pose (``prepare(..., base_velocity="from-pose")``, CLI
``--base-velocity``), after :func:`clip_to_pose` dropped the samples outside the pose's span.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.spatial.transform import Rotation, Slerp

from ..errors import DataError, DataWarning, ShapeMismatchError, TimestampError, setting
from .filtering import SavitzkyGolay, note_processing, default_savgol_window, butter_lowpass, sign_continuous
from .trajectory import Trajectory

__all__ = ["BasePose", "clean_base_pose", "with_base_pose", "clip_to_pose", "base_motion_from_pose",
           "ORIENTATION_FORMATS", "DEFAULT_POSE_MAX_GAP", "pose_from_rpy"]

#: ``quat_xyzw`` (Pinocchio/SciPy order), ``quat_wxyz``, or ``rpy`` (extrinsic x-y-z roll,
#: pitch, yaw [rad], i.e. R = Rz(yaw) Ry(pitch) Rx(roll)).
ORIENTATION_FORMATS = ("quat_xyzw", "quat_wxyz", "rpy")
#: Largest gap inside the pose stream [median periods of the kept samples] that is interpolated:
#: a 100 Hz tracker that loses markers for 0.1 s; longer, a spline through walking motion is a guess
DEFAULT_POSE_MAX_GAP = 10.0
#: a run of identical poses followed by a move smaller than this share of the median sample-to-sample
#: step is a base at rest (kept), not a held tracker output (dropped and interpolated)
REST_STEP_SHARE = 0.1


@dataclass
class BasePose:
    """Base pose [x y z qx qy qz qw] (N, 7), LOCAL twist (N, 6) and its derivative (N, 6) at ``t``;
    ``report`` counts what the cleaning dropped."""

    t: np.ndarray
    base_q: np.ndarray
    base_v: np.ndarray
    base_a: np.ndarray
    report: dict = field(default_factory=dict)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (N, 4) quaternions in (x, y, z, w) order."""
    av, aw, bv, bw = a[:, :3], a[:, 3:], b[:, :3], b[:, 3:]
    return np.hstack([aw * bv + bw * av + np.cross(av, bv), aw * bw - np.sum(av * bv, axis=1, keepdims=True)])


def _rotations(orientation: np.ndarray, fmt: str, src: str) -> np.ndarray:
    """(N, 4) xyzw quaternions (NaN rows kept as NaN)."""
    cols = 3 if fmt == "rpy" else 4
    if orientation.ndim != 2 or orientation.shape[1] != cols:
        raise ShapeMismatchError(f"orientation has shape {orientation.shape}; '{fmt}' needs {cols} columns", src)
    out = np.full((len(orientation), 4), np.nan)
    ok = np.isfinite(orientation).all(axis=1)
    if fmt == "rpy":
        out[ok] = Rotation.from_euler("xyz", orientation[ok]).as_quat()
    else:
        quat = orientation[ok] if fmt == "quat_xyzw" else np.roll(orientation[ok], -1, axis=1)
        norm = np.linalg.norm(quat, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1) > 0.1)
        if bad.size:
            raise DataError(f"orientation sample {np.flatnonzero(ok)[bad[0]]} is not a unit quaternion "
                            f"(norm {norm[bad[0]]:.3g}); check orientation_format ('{fmt}')", src)
        out[ok] = quat / norm[:, None]
    return out


def pose_from_rpy(pose: np.ndarray, src: str = "<log>") -> np.ndarray:
    """[x y z roll pitch yaw] (N, 6) -> [x y z qx qy qz qw] (N, 7) (``rpy`` of :data:`ORIENTATION_FORMATS`;
    a NaN row stays NaN): a base pose logged as position and Euler angles (``--base-rpy``)."""
    pose = np.asarray(pose, dtype=float)
    if pose.ndim != 2 or pose.shape[1] != 6:
        raise ShapeMismatchError(f"'base_q' has shape {pose.shape}; a base pose with Euler angles needs 6 columns "
                                 f"(x y z roll pitch yaw, {setting('base_rpy', True)})", src)
    return np.hstack([pose[:, :3], _rotations(pose[:, 3:], "rpy", src)])


def _valid_samples(t, p, quat, hold_tol: float, source: str) -> tuple[np.ndarray, dict]:
    """Indices of the usable pose samples (step 1 of the module docstring) and their counts.

    A run of identical poses (within ``hold_tol``; q ≡ −q) is a tracker holding its last value, unless
    the pose after it moves by less than :data:`REST_STEP_SHARE` of the median sample-to-sample step:
    then it is a base at rest, and its samples are kept as measured."""
    n = len(t)
    if n < 4:
        raise DataError(f"only {n} pose samples; at least 4 are needed", source)
    finite = np.isfinite(t) & np.isfinite(p).all(axis=1) & np.isfinite(quat).all(axis=1)
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise TimestampError(f"time goes backwards at sample {back[0] + 1} ({t[back[0]]:.6g} → {t[back[0] + 1]:.6g} s)",
                             source)
    dup = np.zeros(n, bool)
    dup[1:] = np.diff(t) == 0
    eq = np.zeros(n, bool)  # same position and rotation as the previous sample
    with np.errstate(invalid="ignore"):
        dot = np.clip(np.abs(np.sum(quat[1:] * quat[:-1], axis=1)), 0.0, 1.0)
        eq[1:] = (finite[1:] & finite[:-1] & np.all(np.abs(np.diff(p, axis=0)) <= hold_tol, axis=1)
                  & (1.0 - dot <= max(hold_tol, 1e-12)))
        step_p, step_r = np.linalg.norm(np.diff(p, axis=0), axis=1), 2.0 * np.arccos(dot)
    moving = finite[1:] & finite[:-1] & ~eq[1:] & ~dup[1:]
    typical = (np.median(step_p[moving]), np.median(step_r[moving])) if moving.any() else (0.0, 0.0)
    edges = np.diff(np.concatenate([[0], eq.astype(np.int8), [0]]))
    first, last = np.flatnonzero(edges == 1) - 1, np.flatnonzero(edges == -1) - 1  # runs first..last identical
    nxt, jump = np.minimum(last + 1, n - 1), np.minimum(last, n - 2)  # the sample after each run, the step to it
    at_rest = (((first == 0) & (last == n - 1))  # a pose that never changes: a base held in place
               | ((last + 1 < n) & finite[nxt] & ~dup[nxt] & (step_p[jump] <= REST_STEP_SHARE * typical[0])
                  & (step_r[jump] <= REST_STEP_SHARE * typical[1])))
    mark = np.zeros(n + 1, int)
    np.add.at(mark, first[~at_rest] + 1, 1)
    np.add.at(mark, last[~at_rest] + 1, -1)
    held = np.cumsum(mark)[:n] > 0
    keep = finite & ~held & ~dup
    idx = np.flatnonzero(keep)
    lead = np.flatnonzero(~at_rest & (first == (idx[0] if idx.size else -1)))
    if lead.size:  # a leading run of repeats: keep its last sample (the tracker's first)
        idx = np.concatenate([[last[lead[0]]], idx[1:]])
    counts = {"n_in": n, "n_nonfinite": int((~finite).sum()), "n_held": int((held & finite).sum()),
              "n_at_rest": int(np.sum(last[at_rest] - first[at_rest] + 1)),
              "leading": int(idx[0]) if idx.size else n, "trailing": int(n - 1 - idx[-1]) if idx.size else 0}
    if idx.size < 4:
        raise DataError(f"only {idx.size} of the {n} pose samples are usable (the others are missing or repeat the "
                        "previous one)", source)
    return idx, counts


def _clip_note(counts: dict, dropped: tuple[int, int], t_lo: float, t_hi: float, source: str) -> str:
    parts = [f"{what}: clipped {k} sample(s) {side} t = {at:.6g} s" for what, k, side, at in (
        (f"the first {counts['leading']} pose sample(s) repeat the next one or are missing (a tracker not yet "
         "tracking)", dropped[0], "before", t_lo),
        (f"the last {counts['trailing']} pose sample(s) repeat the one before them or are missing (a tracker no "
         "longer tracking)", dropped[1], "after", t_hi)) if k]
    return f"{source}: base pose: " + "; ".join(parts)


def clean_base_pose(
    t: np.ndarray,
    position: np.ndarray,
    orientation: np.ndarray,
    *,
    orientation_format: str = "quat_xyzw",
    t_out: np.ndarray | None = None,
    rate: float | None = None,
    cutoff_hz: float | None = 10.0,
    order: int = 4,
    window: int | None = None,
    polyorder: int = 3,
    max_gap: float | None = None,
    max_gap_periods: float = DEFAULT_POSE_MAX_GAP,
    hold_tol: float = 0.0,
    source: str = "<mocap>",
) -> BasePose:
    """Clean, interpolate, low-pass and differentiate a mocap base pose (module docstring).

    ``t`` (N,) [s], ``position`` (N, 3) [m], ``orientation`` (N, 4|3) in ``orientation_format``.
    The work is done on a uniform grid at ``rate`` (default: the median input rate) over the
    valid span; the output is that grid, or ``t_out`` (times within the stream; those before the
    first or after the last valid sample are clipped with a DataWarning, ``BasePose.t`` says which
    remain). ``max_gap`` [s] overrides ``max_gap_periods``. ``cutoff_hz=None`` skips the low-pass;
    ``window`` is the Savitzky–Golay window (default: the package's 0.2 s,
    :func:`~.filtering.default_savgol_window`).
    """
    if orientation_format not in ORIENTATION_FORMATS:
        raise DataError(f"orientation_format must be one of {ORIENTATION_FORMATS}, got {orientation_format!r}", source)
    t = np.asarray(t, float).ravel()
    p = np.asarray(position, float)
    o = np.asarray(orientation, float)
    n = len(t)
    if p.shape != (n, 3) or o.shape[0] != n:
        raise ShapeMismatchError(f"time has {n} samples, position {p.shape}, orientation {o.shape}; "
                                 "expected (N,), (N, 3), (N, 4|3)", source)
    quat = _rotations(o, orientation_format, source)
    idx, counts = _valid_samples(t, p, quat, hold_tol, source)
    gaps = np.diff(t[idx])
    period = float(np.median(gaps))
    limit = float(max_gap) if max_gap is not None else max_gap_periods * period
    worst = int(np.argmax(gaps))
    if gaps[worst] > limit:
        rule = (f"max_gap = {max_gap} s" if max_gap is not None else
                f"{max_gap_periods:g} median pose periods ({limit:.3f} s; {setting('pose_max_gap', placeholder='PERIODS')} "
                "raises it)")
        raise DataError(f"the base pose has a {gaps[worst]:.3f} s gap (held or missing) from t = {t[idx[worst]]:.3f} s "
                        f"to {t[idx[worst + 1]]:.3f} s, longer than {rule}; or trim the log around it ({setting('trim')})", source)
    tv, pv, qv = t[idx], p[idx], quat[idx]
    h = 1.0 / rate if rate else period
    grid = np.minimum(tv[0] + h * np.arange(int(np.floor((tv[-1] - tv[0]) / h + 1e-9)) + 1), tv[-1])
    report = {**counts, "max_gap": float(gaps[worst]), "max_gap_limit": limit, "cutoff_hz": cutoff_hz}
    if t_out is not None:
        t_out = np.asarray(t_out, float)
        if t_out[0] < t[0] - 1e-9 or t_out[-1] > t[-1] + 1e-9:
            raise DataError(f"output times {t_out[0]:.3f}..{t_out[-1]:.3f} s reach outside the pose stream "
                            f"{t[0]:.3f}..{t[-1]:.3f} s", source)
        inside = (t_out >= tv[0] - 1e-9) & (t_out <= tv[-1] + 1e-9)
        dropped = (int(np.sum(t_out < tv[0] - 1e-9)), int(np.sum(t_out > tv[-1] + 1e-9)))
        if not inside.any():
            raise DataError(f"no output time lies within the valid pose samples {tv[0]:.3f}..{tv[-1]:.3f} s", source)
        if any(dropped):
            warnings.warn(_clip_note(counts, dropped, tv[0], tv[-1], source), DataWarning, stacklevel=2)
        t_out = t_out[inside]
        report["clipped"] = dropped
    # everything is computed on a uniform grid over the valid span (edge effects stay at its ends)
    pos = make_interp_spline(tv, pv, k=3)(grid)
    qs = sign_continuous(Slerp(tv, Rotation.from_quat(qv))(grid).as_quat())  # for filtering and differentiation
    if cutoff_hz is not None:
        pos = butter_lowpass(pos, cutoff_hz, 1.0 / h, order)
        qs = butter_lowpass(qs, cutoff_hz, 1.0 / h, order)
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    sg = SavitzkyGolay(window=window or default_savgol_window(1.0 / h), polyorder=polyorder, dt=h)
    dp, ddp = sg.apply(pos, 1), sg.apply(pos, 2)
    dq, ddq = sg.apply(qs, 1), sg.apply(qs, 2)
    conj = qs * np.array([-1.0, -1.0, -1.0, 1.0])
    w = 2.0 * _qmul(conj, dq)[:, :3]
    dw = 2.0 * _qmul(conj, ddq)[:, :3]
    R = Rotation.from_quat(qs).as_matrix()
    v = np.einsum("nji,nj->ni", R, dp)
    a_lin = np.einsum("nji,nj->ni", R, ddp) - np.cross(w, v)
    twist, acc = np.hstack([v, w]), np.hstack([a_lin, dw])
    if t_out is None:
        t_out = grid
    else:  # evaluate at the requested times: splines for vectors, Slerp for the orientation
        t_out = np.clip(t_out, grid[0], grid[-1])
        pos = make_interp_spline(grid, pos, k=3)(t_out)
        qs = Slerp(grid, Rotation.from_quat(qs))(t_out).as_quat()
        twist = make_interp_spline(grid, twist, k=3)(t_out)
        acc = make_interp_spline(grid, acc, k=3)(t_out)
    report.update(n_out=len(t_out), window=sg.window)
    return BasePose(t_out, np.hstack([pos, qs]), twist, acc, report)


def with_base_pose(traj: Trajectory, t: np.ndarray, position: np.ndarray, orientation: np.ndarray, **kw) -> Trajectory:
    """``traj`` with ``base_q``, ``base_v``, ``base_a`` from a mocap stream (:func:`clean_base_pose`
    evaluated at ``traj.t``, which must lie inside the mocap time span; samples before the first or
    after the last valid pose sample are dropped with a DataWarning)."""
    pose = clean_base_pose(t, position, orientation, t_out=traj.t, source=kw.pop("source", traj.source), **kw)
    if len(pose.t) != len(traj):
        traj = traj.take((traj.t >= pose.t[0]) & (traj.t <= pose.t[-1]))
    r = pose.report
    note = (f"base pose from mocap: {r['n_held']} held and {r['n_nonfinite']} missing samples "
            f"dropped, spline/Slerp, low-pass {r['cutoff_hz']} Hz, savgol({r['window']}) derivatives")
    return traj.with_(base_q=pose.base_q, base_v=pose.base_v, base_a=pose.base_a, units=note_processing(traj, note))


def clip_to_pose(traj: Trajectory, hold_tol: float = 0.0) -> Trajectory:
    """``traj`` without the samples before its first or after its last valid ``base_q`` sample
    (leading and trailing repeats, or missing poses), with a DataWarning counting them."""
    if traj.base_q is None:
        raise DataError("the log has no base pose ('base_q')", traj.source)
    bq = np.asarray(traj.base_q, float)
    idx, counts = _valid_samples(traj.t, bq[:, :3], bq[:, 3:], hold_tol, traj.source)
    if counts["leading"] == 0 and counts["trailing"] == 0:
        return traj
    lo, hi = int(idx[0]), int(idx[-1])
    warnings.warn(_clip_note(counts, (lo, len(traj) - 1 - hi), traj.t[lo], traj.t[hi], traj.source), DataWarning,
                  stacklevel=2)
    out = traj.take(slice(lo, hi + 1))
    return out.with_(provenance={**out.provenance, "base_pose_clipped": {"leading": lo, "trailing": len(traj) - 1 - hi,
                                                                        "t_start": float(out.t[0]),
                                                                        "t_end": float(out.t[-1])}})


def base_motion_from_pose(traj: Trajectory, t: np.ndarray, base_q: np.ndarray, *, cutoff_hz: float | None,
                          window: int | None, max_gap_periods: float = DEFAULT_POSE_MAX_GAP,
                          keep_base_a: bool = False) -> Trajectory:
    """``traj`` with ``base_q``, ``base_v`` (and ``base_a``, unless ``keep_base_a``) from the pose samples
    ``(t, base_q)`` it was logged with (before resampling): :func:`clean_base_pose` at ``traj.t`` with the
    log's low-pass ``cutoff_hz`` and derivative ``window``; provenance says how."""
    bq = np.asarray(base_q, float)
    pose = clean_base_pose(t, bq[:, :3], bq[:, 3:], t_out=traj.t, cutoff_hz=cutoff_hz, window=window,
                           max_gap_periods=max_gap_periods, source=traj.source)
    if len(pose.t) != len(traj):
        traj = traj.take((traj.t >= pose.t[0]) & (traj.t <= pose.t[-1]))
    r = pose.report
    how = (f"derived from the logged base pose (clean_base_pose: {r['n_held']} repeated and {r['n_nonfinite']} missing "
           f"pose samples dropped, largest gap {r['max_gap']:.3g} s of {r['max_gap_limit']:.3g} s allowed, spline/Slerp, "
           f"low-pass {'off' if cutoff_hz is None else f'{cutoff_hz:g} Hz'}, Savitzky-Golay window {r['window']})")
    prov = {**traj.provenance, "base_q": "logged; repeats and gaps interpolated, low-passed with base_v", "base_v": how}
    kw = dict(base_q=pose.base_q, base_v=pose.base_v)
    if not keep_base_a:
        kw["base_a"] = pose.base_a
        prov["base_a"] = how
    return traj.with_(**kw, provenance=prov, units=note_processing(traj, "base_v" + ("" if keep_base_a else ", base_a")
                                                         + " from the base pose (clean_base_pose)"))

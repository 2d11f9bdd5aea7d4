"""Base pose, twist and acceleration from motion capture that holds, drops and wraps.

Mocap base poses arrive with repeated samples (the tracker holds its last value when it
loses the markers), NaN gaps, duplicate or jittery stamps, Euler yaw that wraps at ±π
and quaternions whose sign flips. :func:`clean_base_pose` turns them into Pinocchio's
floating-base convention on a uniform (or given) time grid:

1. **clean**: non-finite samples, held samples (position and rotation identical to the
   previous sample's, within ``hold_tol``) and duplicate stamps are dropped; a remaining gap longer than
   ``max_gap`` is an error naming where it is.
2. **interpolate**: positions by a cubic spline (``scipy.interpolate.make_interp_spline``),
   orientations by ``scipy.spatial.transform.Slerp`` (shortest arc: yaw wrap and the
   quaternion sign do not matter).
3. **low-pass**: zero-phase Butterworth (:func:`~.filtering.butter_lowpass`) on p and on
   the sign-continuous quaternion, renormalised.
4. **differentiate**: Savitzky–Golay (:class:`~.filtering.SavitzkyGolay`) ṗ, p̈, q̇, q̈, then
   the LOCAL twist and its derivative (Pinocchio's free-flyer)::

       v = Rᵀ ṗ,   ω = 2 vec(q̄ ⊗ q̇),   a_lin = Rᵀ p̈ − ω × v,   ω̇ = 2 vec(q̄ ⊗ q̈)

   (d/dt(q̄ ⊗ q̇) = q̄ ⊗ q̈ + |q̇|², whose vector part is that of q̄ ⊗ q̈).

:func:`with_base_pose` fills ``base_q``, ``base_v``, ``base_a`` of a joint log from a
mocap stream on another clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.spatial.transform import Rotation, Slerp

from ..errors import DataError, ShapeMismatchError, TimestampError
from .filtering import SavitzkyGolay, _note, default_savgol_window, butter_lowpass
from .trajectory import Trajectory

__all__ = ["BasePose", "clean_base_pose", "with_base_pose", "ORIENTATION_FORMATS"]

#: ``quat_xyzw`` (Pinocchio/SciPy order), ``quat_wxyz``, or ``rpy`` (extrinsic x-y-z roll,
#: pitch, yaw [rad], i.e. R = Rz(yaw) Ry(pitch) Rx(roll)).
ORIENTATION_FORMATS = ("quat_xyzw", "quat_wxyz", "rpy")


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
    max_gap: float = 0.25,
    hold_tol: float = 0.0,
    source: str = "<mocap>",
) -> BasePose:
    """Clean, interpolate, low-pass and differentiate a mocap base pose (module docstring).

    ``t`` (N,) [s], ``position`` (N, 3) [m], ``orientation`` (N, 4|3) in ``orientation_format``.
    The work is done on a uniform grid at ``rate`` (default: the median input rate) over the
    valid span; the output is that grid, or ``t_out`` (any times within the valid samples). ``cutoff_hz=None`` skips the low-pass; ``window`` is the
    Savitzky–Golay window (default: the package's 0.2 s, :func:`~.filtering.default_savgol_window`).
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
    finite = np.isfinite(t) & np.isfinite(p).all(axis=1) & np.isfinite(quat).all(axis=1)
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise TimestampError(f"time goes backwards at sample {back[0] + 1} ({t[back[0]]:.6g} → {t[back[0] + 1]:.6g} s)",
                             source)
    same = np.zeros(n, bool)  # held: same position and rotation (q ≡ −q) as the previous sample
    dot = np.abs(np.sum(quat[1:] * quat[:-1], axis=1))
    same[1:] = ((np.all(np.abs(np.diff(p, axis=0)) <= hold_tol, axis=1) & (1.0 - dot <= max(hold_tol, 1e-12)))
                | (np.diff(t) == 0))
    keep = finite & ~same
    idx = np.flatnonzero(keep)
    if idx.size < 4:
        raise DataError(f"only {idx.size} usable pose samples after dropping non-finite and held ones", source)
    gaps = np.diff(t[idx])
    worst = int(np.argmax(gaps))
    if gaps[worst] > max_gap:
        raise DataError(f"the base pose has a {gaps[worst]:.3f} s gap (held or missing) from t = {t[idx[worst]]:.3f} s "
                        f"to {t[idx[worst + 1]]:.3f} s, longer than max_gap = {max_gap} s", source)
    tv, pv, qv = t[idx], p[idx], quat[idx]
    h = 1.0 / rate if rate else float(np.median(np.diff(tv)))
    grid = np.minimum(tv[0] + h * np.arange(int(np.floor((tv[-1] - tv[0]) / h + 1e-9)) + 1), tv[-1])
    if t_out is not None:
        t_out = np.asarray(t_out, float)
        if t_out[0] < tv[0] - 1e-9 or t_out[-1] > tv[-1] + 1e-9:
            raise DataError(f"output times {t_out[0]:.3f}..{t_out[-1]:.3f} s reach outside the valid pose samples "
                            f"{tv[0]:.3f}..{tv[-1]:.3f} s", source)
    # everything is computed on a uniform grid over the valid span (edge effects stay at its ends)
    pos = make_interp_spline(tv, pv, k=3)(grid)
    qs = Slerp(tv, Rotation.from_quat(qv))(grid).as_quat()
    flip = np.cumprod(np.where(np.sum(qs[1:] * qs[:-1], axis=1) < 0, -1.0, 1.0))
    qs[1:] *= flip[:, None]  # sign-continuous for filtering and differentiation
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
    report = {"n_in": n, "n_nonfinite": int((~finite).sum()), "n_held": int((same & finite).sum()),
              "max_gap": float(gaps[worst]), "n_out": len(t_out), "cutoff_hz": cutoff_hz, "window": sg.window}
    return BasePose(t_out, np.hstack([pos, qs]), twist, acc, report)


def with_base_pose(traj: Trajectory, t: np.ndarray, position: np.ndarray, orientation: np.ndarray, **kw) -> Trajectory:
    """``traj`` with ``base_q``, ``base_v``, ``base_a`` from a mocap stream (:func:`clean_base_pose`
    evaluated at ``traj.t``, which must lie inside the mocap time span)."""
    pose = clean_base_pose(t, position, orientation, t_out=traj.t, source=kw.pop("source", traj.source), **kw)
    note = (f"base pose from mocap: {pose.report['n_held']} held and {pose.report['n_nonfinite']} missing samples "
            f"dropped, spline/Slerp, low-pass {pose.report['cutoff_hz']} Hz, savgol({pose.report['window']}) derivatives")
    return traj.with_(base_q=pose.base_q, base_v=pose.base_v, base_a=pose.base_a, units=_note(traj, note))

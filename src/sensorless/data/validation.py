"""Checks that turn a raw :class:`Trajectory` into one identification can trust.

:func:`validate_trajectory` checks shapes, finiteness, strictly increasing time and
the sample count. Given a robot, it also reorders the joints to ``robot.joint_names``
and checks for values that look like degrees or encoder counts. Every failure is a
typed :mod:`sensorless.errors` exception that names the field, the joint column and
the first bad sample.
"""

from __future__ import annotations

import os
import warnings
from typing import TYPE_CHECKING

import numpy as np

from ..errors import (
    DataError,
    DataWarning,
    JointNameError,
    NonFiniteError,
    OutlierError,
    ShapeMismatchError,
    TimestampError,
    TooFewSamplesError,
    UnitsError,
    python_only,
    setting,
)
from .bad_rows import max_edge_rows, scan_rows
from .trajectory import Trajectory, as_float_array
from .trims import TrimWindow, trim_window

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["validate_trajectory", "JOINT_EXTRAS", "MAX_ABS_VALUE"]

#: ``extras`` keys holding one column per joint; they are reordered with the joints.
JOINT_EXTRAS = ("current", "command", "tau_out", "q_motor")

_JOINT_FIELDS = ("q", "v", "a", "tau")
_BASE_COLS = {"base_q": 7, "base_v": 6, "base_a": 6}
_LIMIT_MARGIN = 0.5  # rad: slack beyond the model limits before values look like degrees
_MAX_REVOLUTE_Q = 100.0  # rad: no revolute joint travels ~16 turns in one log
_MAX_REVOLUTE_V = 100.0  # rad/s
#: No SI signal of a robot log (rad, m, rad/s, N·m, N, A) reaches this magnitude; beyond it the
#: values are in the wrong unit or corrupt, and their squares would overflow the normal equations.
MAX_ABS_VALUE = 1e9


def validate_trajectory(
    traj: Trajectory,
    robot: "Robot | None" = None,
    *,
    check_units: bool = True,
    min_samples: int = 2,
    allow_duplicate_times: bool = False,
    outliers: str = "keep",
    trim: "str | tuple | TrimWindow | None" = None,
    skip_bad_rows: bool = False,
) -> Trajectory:
    """Check ``traj`` and return it (reordered to ``robot.joint_names`` if a robot is given).

    ``allow_duplicate_times`` accepts repeated time stamps (time must still never go
    backwards); :func:`sensorless.data.resample` merges them.

    Before the checks, ``skip_bad_rows`` drops a corrupt prefix and suffix
    (:mod:`~sensorless.data.bad_rows`, with a DataWarning saying which samples and why;
    ``provenance["rows_dropped"]``), then ``trim`` cuts a time window
    (:func:`~sensorless.data.trim_window`, relative to the first row kept). Errors name the
    sample as a row of the log as given; an error at a corrupt prefix or suffix says how to
    drop it.

    Raises ShapeMismatchError, NonFiniteError, TimestampError, JointNameError,
    UnitsError or TooFewSamplesError. ``outliers`` ("error" | "drop" | "keep") handles gross
    outliers (:mod:`~sensorless.data.outliers`, OutlierError or dropped samples). With
    ``check_units`` any value beyond :data:`MAX_ABS_VALUE` is a UnitsError. The input is never
    modified.
    """
    from .outliers import handle_outliers

    if not isinstance(traj, Trajectory):
        raise DataError(f"expected a Trajectory, got {type(traj).__name__}")
    src = traj.source
    traj = _passive_torques(traj, robot)
    t = as_float_array(traj.t, "t", src)
    if t.ndim != 1:
        raise ShapeMismatchError(f"'t' must be 1-D, got shape {t.shape}", src)
    n = t.shape[0]
    if n < min_samples:
        raise TooFewSamplesError(f"only {n} sample(s); at least {min_samples} are needed", src)

    names = list(traj.joint_names)
    if not all(isinstance(j, str) and j for j in names):
        raise JointNameError(f"joint names must be non-empty strings, got {names}", src)
    dup = sorted({j for j in names if names.count(j) > 1})
    if dup:
        raise JointNameError(f"duplicate joint name(s) {dup} in {names}", src)

    arrays: dict[str, np.ndarray] = {}
    for name in _JOINT_FIELDS + tuple(_BASE_COLS):
        val = getattr(traj, name)
        if val is None:
            if name == "q":
                raise ShapeMismatchError("'q' (joint positions) is missing", src)
            continue
        arr = as_float_array(val, name, src)
        cols = _BASE_COLS.get(name, len(names))
        if arr.ndim == 1 and cols == 1:
            arr = arr[:, None]
        if arr.ndim != 2:
            raise ShapeMismatchError(f"'{name}' must be 2-D (samples x columns), got shape {arr.shape}", src)
        if arr.shape[0] != n:
            raise ShapeMismatchError(f"row count of '{name}' is {arr.shape[0]} but 't' has {n} samples", src)
        if arr.shape[1] != cols:
            what = f"there are {cols} joint names" if name in _JOINT_FIELDS else f"'{name}' needs {cols}"
            hint = (f"; a joint without an actuator has no torque column: declare it passive ({setting('passive_joints', placeholder='JOINT')})"
                    if name == "tau" and arr.shape[1] < cols else "")
            raise ShapeMismatchError(f"column count of '{name}' is {arr.shape[1]} but {what}{hint}", src)
        arrays[name] = arr
    for key, val in traj.extras.items():
        arr = np.asarray(val)
        if arr.ndim == 0 or arr.shape[0] != n:
            raise ShapeMismatchError(f"extras['{key}'] has shape {arr.shape} but 't' has {n} samples", src)
        if key in JOINT_EXTRAS:
            arr = as_float_array(arr, key, src)
            if arr.ndim != 2:
                raise ShapeMismatchError(f"extras['{key}'] has shape {arr.shape}; expected (samples, columns)", src)

    raw, t0 = traj.with_(t=t, **arrays), t
    traj, scan = raw, None
    rows = np.arange(n)  # the log's own row of each sample, for the messages
    if skip_bad_rows:
        scan = scan_rows(t, _columns(traj, names), allow_duplicate_times)
        if scan.dropped:
            rows = scan.keep()
            traj = traj.take(rows if scan.isolated else slice(scan.start, scan.stop))
            traj = traj.with_(provenance={**traj.provenance, "rows_dropped": scan.to_dict()})
            warnings.warn(f"{src}: {setting('skip_bad_rows', True)} dropped {scan.describe()}", DataWarning, stacklevel=2)
    if trim is not None:
        keep = trim_window(traj.with_(extras={**traj.extras, _ROWS: rows}), trim)
        rows = keep.extras.pop(_ROWS)
        traj = keep
    t = traj.t
    arrays = {k: getattr(traj, k) for k in arrays}
    try:
        _check_finite("t", t[:, None], ["t"], t, src, rows)
        for name, arr in arrays.items():
            labels = names if name in _JOINT_FIELDS else [f"{name}[{k}]" for k in range(arr.shape[1])]
            _check_finite(name, arr, labels, t, src, rows)
        for key in JOINT_EXTRAS:
            if key in traj.extras:
                arr = as_float_array(traj.extras[key], key, src)
                labels = names if arr.shape[1] == len(names) else [f"{key}[{k}]" for k in range(arr.shape[1])]
                _check_finite(key, arr, labels, t, src, rows)
        _check_time(t, src, allow_duplicate_times, rows)
        out = handle_outliers(traj, outliers)
        if len(out) < min_samples:
            raise TooFewSamplesError(f"only {len(out)} sample(s) left after dropping outliers; at least {min_samples} "
                                     "are needed", src)
        if check_units:
            _check_magnitude(out, rows if len(out) == len(rows) else None)
    except (NonFiniteError, TimestampError, UnitsError, OutlierError) as exc:
        raise _with_hint(exc, scan, lambda: scan_rows(t0, _columns(raw, names), allow_duplicate_times), rows) from None
    if robot is None:
        return out
    perm = robot.joint_order(names, src)  # JointNameError for unknown / missing / duplicates
    if not np.array_equal(perm, np.arange(len(names))):
        extras = {
            k: (np.asarray(v)[:, perm] if k in JOINT_EXTRAS and np.ndim(v) == 2 and np.shape(v)[1] == len(perm) else v)
            for k, v in out.extras.items()
        }
        out = out.select_joints(list(robot.joint_names)).with_(extras=extras)
    if check_units:
        _check_units(out, robot)
    return out


_ROWS = "__rows__"  # extras key carrying each sample's row through a trim


def _columns(traj: Trajectory, names: list[str]) -> list:
    """(field, (N, k) array, labels) of every per-sample signal the checks look at."""
    cols = []
    for name in _JOINT_FIELDS + tuple(_BASE_COLS):
        arr = getattr(traj, name)
        if arr is not None:
            arr = np.asarray(arr, dtype=float).reshape(len(traj), -1)
            cols.append((name, arr, names if name in _JOINT_FIELDS else [f"{name}[{k}]" for k in range(arr.shape[1])]))
    for key in JOINT_EXTRAS:
        arr = traj.extras.get(key)
        if arr is not None:
            arr = np.asarray(arr, dtype=float).reshape(len(traj), -1)
            cols.append((key, arr, names if arr.shape[1] == len(names) else [f"{key}[{k}]" for k in range(arr.shape[1])]))
    return cols


def _with_hint(exc: DataError, scan, rescan, checked: np.ndarray) -> DataError:
    """``exc`` with what --skip-bad-rows does about it: drops a corrupt prefix/suffix the log has
    (``scan`` None: not asked for; ``rescan()`` finds them, unless a trim left them out of the
    ``checked`` rows), or cannot drop this (middle)."""
    if scan is None:
        scan = rescan()
        inside = any(np.any((checked >= e.first) & (checked <= e.last)) for e in scan.edges)
        if not inside:
            return exc
        hint = f"; the log has {scan.describe()}: rerun with {setting('skip_bad_rows', True)} to drop them"
        if scan.window is not None:
            lo, hi = scan.window
            name = os.path.basename(str(exc.source)) if exc.source else "FILE"
            lost = f", which also leaves out {scan.window_loses} clean row(s)" if scan.window_loses else ""
            hint += f", or cut them away with {setting('trim', f'{name}=abs:{lo:.6f}:{hi:.6f}')}{lost}"
        if scan.middle:
            hint += f"; it is corrupt in the middle too, at {scan.middle}, which {setting('skip_bad_rows')} does not drop"
    else:
        dropped = f" (it dropped {scan.describe()})" if scan.edges else ""
        hint = (f"; {setting('skip_bad_rows')} drops only a corrupt prefix or suffix of at most {max_edge_rows(scan.n)} "
                f"rows{dropped}, and this is in the middle of the log: cut the log there with {setting('trim')} (or split it)")
    msg = str(exc)
    if exc.source and msg.startswith(f"{exc.source}: "):
        msg = msg[len(exc.source) + 2:]
    return type(exc)(msg + hint, exc.source)


def _passive_torques(traj: Trajectory, robot: "Robot | None") -> Trajectory:
    """A passive joint (``robot.passive_joints``) has no torque channel: ``tau`` may omit its columns
    (one column per other joint, in the log's order) or hold anything there (NaN included); either
    way its torque becomes 0, the generalized force of a joint without actuator."""
    passive = tuple(getattr(robot, "passive_joints", ()) or ()) if robot is not None else ()
    if not passive or traj.tau is None:
        return traj
    names = list(traj.joint_names)
    idx = [k for k, j in enumerate(names) if j in passive]
    if not idx:
        return traj
    tau = np.asarray(traj.tau, dtype=float)
    tau = tau[:, None] if tau.ndim == 1 else tau
    if tau.ndim == 2 and tau.shape[1] == len(names) - len(idx):
        full = np.zeros((tau.shape[0], len(names)))
        full[:, [k for k in range(len(names)) if k not in idx]] = tau
        return traj.with_(tau=full)
    if tau.ndim == 2 and tau.shape[1] == len(names):
        tau = tau.copy()
        tau[:, idx] = 0.0
        return traj.with_(tau=tau)
    return traj  # the shape check below names the mismatch


def _check_finite(name: str, arr: np.ndarray, labels: list[str], t: np.ndarray, src: str,
                  row: "np.ndarray | None" = None) -> None:
    bad = ~np.isfinite(arr)
    if not bad.any():
        return
    i = int(np.argmax(bad.any(axis=1)))  # earliest bad sample, then its first bad column
    col = int(np.argmax(bad[i]))
    rows = np.flatnonzero(bad[:, col])
    where = f"sample {i if row is None else int(row[i])}" + (f" (t={t[i]:.3f} s)" if np.isfinite(t[i]) and name != "t" else "")
    what = f"'{name}'" if name == "t" else f"'{name}' column '{labels[col]}'"
    others = int(bad.any(axis=0).sum()) - 1
    more = f"; {others} other column(s) too" if others else ""
    raise NonFiniteError(f"{what} has {rows.size} non-finite values (NaN/inf), first at {where}{more}", src)


def _check_magnitude(traj: Trajectory, row: "np.ndarray | None" = None) -> None:
    fields = [(f, getattr(traj, f)) for f in _JOINT_FIELDS + tuple(_BASE_COLS)] + [
        (k, traj.extras.get(k)) for k in JOINT_EXTRAS]
    for name, arr in fields:
        if arr is None:
            continue
        arr = np.asarray(arr, dtype=float).reshape(len(traj), -1)
        big = np.abs(arr) > MAX_ABS_VALUE
        if big.any():
            i, c = (int(x) for x in np.argwhere(big)[0])
            col = traj.joint_names[c] if arr.shape[1] == traj.n_joints and name not in _BASE_COLS else f"{name}[{c}]"
            raise UnitsError(
                f"'{name}' column '{col}' reaches {arr[i, c]:.3g} at sample {i if row is None else int(row[i])} "
                f"(|value| > {MAX_ABS_VALUE:.0e}): "
                "no robot signal is that large in SI units; wrong unit or corrupt data", traj.source)


def _check_time(t: np.ndarray, src: str, allow_duplicates: bool = False, row: "np.ndarray | None" = None) -> None:
    dt = np.diff(t)
    bad = np.flatnonzero(dt < 0 if allow_duplicates else dt <= 0)
    if bad.size == 0:
        return
    i = int(bad[0]) + 1
    k = i if row is None else int(row[i])
    p = i - 1 if row is None else int(row[i - 1])
    kind = "duplicate timestamp" if dt[i - 1] == 0 else "time goes backwards"
    hint = (f"; resampling merges duplicate stamps: {setting('resample', 'auto')}" + python_only(
        "read_trajectory(..., allow_duplicate_times=True), then sensorless.data.prepare(traj, resample='auto')")
        if kind == "duplicate timestamp" else "")
    raise TimestampError(
        f"{kind} at sample {k}: t[{k}]={t[i]:.6f} s after t[{p}]={t[i - 1]:.6f} s "
        f"({bad.size} non-increasing step(s) in total); time must be strictly increasing{hint}",
        src,
    )


def _degrees_fix(traj: Trajectory, unit: str = "radians") -> str:
    """How to read a log whose angles look like degrees: ``angle_unit='deg'``, or, when they were
    already converted from degrees, that the unit is another."""
    if "angles" in traj.units:
        return f"they were read as degrees ({setting('angle_unit', 'deg')}) and still look wrong: encoder counts?"
    return f"if the log is in degrees, read it with {setting('angle_unit', 'deg')}, else convert to {unit}"


def _check_units(traj: Trajectory, robot: "Robot") -> None:
    lo, hi = robot.position_limits()
    for j, name in enumerate(traj.joint_names):
        if not robot.is_revolute(name):
            continue
        q = traj.q[:, j]
        k = int(np.argmax(np.abs(q)))
        qmax = abs(q[k])
        bound = max(abs(lo[j]), abs(hi[j]))
        if not robot.is_continuous(name) and np.isfinite(bound) and qmax > bound + _LIMIT_MARGIN:
            q_rad = np.deg2rad(q)
            if q_rad.min() >= lo[j] - _LIMIT_MARGIN and q_rad.max() <= hi[j] + _LIMIT_MARGIN:
                raise UnitsError(
                    f"joint '{name}' positions reach {q[k]:.1f}, beyond its limits "
                    f"[{lo[j]:.2f}, {hi[j]:.2f}] rad: they look like degrees; {_degrees_fix(traj)}",
                    traj.source,
                )
        if qmax > _MAX_REVOLUTE_Q:
            raise UnitsError(
                f"joint '{name}' positions reach {q[k]:.1f} rad (> {_MAX_REVOLUTE_Q:.0f} rad): "
                f"they look like degrees or encoder counts; {_degrees_fix(traj)}",
                traj.source,
            )
        if traj.v is not None:
            v = traj.v[:, j]
            k = int(np.argmax(np.abs(v)))
            if abs(v[k]) > _MAX_REVOLUTE_V:
                raise UnitsError(
                    f"joint '{name}' velocities reach {v[k]:.1f} rad/s (> {_MAX_REVOLUTE_V:.0f} rad/s): "
                    f"they look like deg/s or encoder counts per second; {_degrees_fix(traj, 'rad/s')}",
                    traj.source,
                )

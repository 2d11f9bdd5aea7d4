"""Read logs (CSV and whitespace text, NPZ, Parquet, HDF5, MATLAB .mat, Arrow IPC / Feather, a folder of
per-signal text files; ROS bags and MCAP via :mod:`.rosbag`) into a validated :class:`Trajectory`.
The format of a path is the first of the registry :mod:`.formats` that claims it (``sniff``).

Fields are ``t, q, v, a, tau`` (plus ``current``, ``command`` → ``extras`` and
``base_q, base_v, base_a``). Without ``columns`` each field is found under one of the names of
:data:`~sensorless.data.names.FIELD_NAMES` (one table for every format: ``dq``/``qd``/``v`` are
velocities, ``ddq``/``qdd``/``a`` accelerations, ``effort``/``torque``/``tau`` torques, ...);
every array, column or file no field uses is named in one warning. ``columns`` maps a field to
where it is stored:

* NPZ / HDF5 / MAT: an array key (HDF5: dataset path, MAT: variable or struct field path
  ``data/q``; a unique last component suffices). Array files may store channels × samples
  (:mod:`.orientation`); MATLAB files: :mod:`.matlab`.
* CSV / text / Parquet: a list of column names (or 0-based indices), a pattern with
  ``"{joint}"`` (``"pos_{joint}"``) expanded over the joint names, or an index range
  ``"0:7"`` (the only option for a header-less file). With a header and no ``columns``
  the defaults are a time column (``t``, ``time``, ``tick``, ...) and the header's naming
  convention (:func:`.tabular.detect_patterns`: ``q_{joint}``, ``pos_{joint}``,
  ``{joint}_position``, ``{joint}.velocity`` ...); the joint names come from the position columns.
* A folder of per-signal files (``q.dat``, ``tau.dat``, ...): a file name per field
  (:mod:`.textlog`).

Joint names: ``joint_names``, else names stored in the file (a ``joint_names`` or ``names`` array, or one
mapped under the file's own name, ``columns={"joint_names": "estimatorJointNames"}``; the ``{joint}`` pattern
or a shared header), else ``robot.joint_names`` if the column count matches: refused when the file holds
text arrays the reader did not use (the log's own names, in its own order) unless the read option
``joint_order="model"`` confirms the model's order; else ``joint_0..joint_{n-1}``. Named columns are matched
to the model by name (reordered by validation). Time is converted to seconds (:mod:`.timebase`:
``time_unit`` s, ms, us, ns, or tick with ``rate`` ticks per second; a tick column read
without a unit is refused); without a time field, ``t = arange(N) / rate``.

Currents: ``gains`` (or a ``':gain=...'`` suffix on the ``tau``/``current`` entry of
``columns``, e.g. ``{"tau": "i_{joint}:gain=10,10.7,9.6"}``; ``i_*`` = ``i_{joint}``)
turn logged motor currents into torques τ = K·i, see :mod:`sensorless.data.gains`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..errors import DataError, ShapeMismatchError, setting
from ..io import check_input_file
from .angles import check_angle_unit, to_radians
from .arrays import EXTRA_KEYS, as_float
from .formats import SUPPORTED_EXTENSIONS, find_format
from .gains import currents_to_torques, split_gain_modifiers
from .imu import IMU_KEY
from .limits import current_options, read_options
from .names import FIELD_NAMES, RawLog, short_list, warn_unused
from .orientation import orient_samples
from .tabular import Columns
from .timebase import check_rate, check_time_unit, to_seconds
from .trajectory import Trajectory, as_float_array
from .validation import JOINT_EXTRAS, validate_trajectory

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["read_trajectory", "write_npz", "FIELDS", "JOINT_ORDERS", "TIME_SOURCES"]

FIELDS = tuple(FIELD_NAMES)
_NPZ_KEYS = {"t": "times", "q": "positions", "v": "velocities", "a": "accelerations", "tau": "torques"}


def read_trajectory(
    path: str | Path,
    *,
    joint_names: Sequence[str] | None = None,
    columns: Columns | None = None,
    rate: float | None = None,
    robot: "Robot | None" = None,
    time_unit: str | None = None,
    gains: Any = None,
    allow_duplicate_times: bool = False,
    outliers: str = "error",
    max_memory: "str | int | None" = None,
    allow_external: bool | None = None,
    skip_bad: bool | None = None,
    trim=None,
    skip_bad_rows: bool | None = None,
    angle_unit: str | None = None,
) -> Trajectory:
    """Read a log and return it validated (and reordered to ``robot.joint_names``).

    ``rate`` [Hz] builds the time axis when the file has none. ``time_unit`` (one of
    s, ms, us, ns) converts a stored time column to seconds. ``gains`` are per-joint
    drive gains K (number, list in the log's column order, ``{joint: K}``, or a .json/.csv
    file): the logged currents become τ = K·i (:func:`~sensorless.data.gains.currents_to_torques`).
    ``allow_duplicate_times`` accepts repeated stamps for :func:`sensorless.data.prepare`
    to merge. ``outliers``: gross outliers (:mod:`~sensorless.data.outliers`) raise an
    OutlierError ("error", default), are dropped with a warning ("drop") or kept ("keep").
    Every problem raises a :class:`~sensorless.errors.DataError` subclass naming the file,
    column and row. ``max_memory`` (bytes or '8GiB'), ``allow_external`` (HDF5 external/virtual
    datasets), ``skip_bad`` (corrupt bag/MCAP chunks) and ``skip_bad_rows`` (default False) are
    :mod:`sensorless.data.limits` options. ``skip_bad_rows`` drops a corrupt prefix/suffix of rows
    and ``trim`` (a :class:`~sensorless.data.TrimWindow`) cuts a time window, both before the checks
    (:func:`~sensorless.data.validate_trajectory`). ``angle_unit="deg"``: q, v, v̇ of the revolute
    joints are logged in degrees and converted (:mod:`~sensorless.data.angles`; default "rad", or the
    ``angle_unit`` of :func:`~sensorless.data.limits.read_options`).
    """
    with read_options(max_memory=max_memory, allow_external=allow_external, skip_bad=skip_bad,
                      skip_bad_rows=skip_bad_rows):
        return _read_trajectory(Path(path), joint_names, columns, rate, robot, time_unit, gains,
                                allow_duplicate_times, outliers, trim, angle_unit)


def _read_trajectory(path: Path, joint_names, columns, rate, robot, time_unit, gains, allow_duplicate_times,
                     outliers, trim=None, angle_unit=None) -> Trajectory:
    rows = {"trim": trim, "skip_bad_rows": bool(current_options().get("skip_bad_rows"))}
    angle_unit = check_angle_unit(angle_unit if angle_unit is not None else current_options().get("angle_unit"),
                                  str(path))
    src = str(path)
    if not path.exists():
        raise DataError("no such file", src)
    if not path.is_dir():
        check_input_file(path, "log file")  # a FIFO or device would block or never end
    fmt = find_format(path)
    if fmt is not None and fmt.trajectory:  # e.g. a ROS 1/2 bag or MCAP: topics instead of columns
        return fmt.read(path, columns, joint_names, robot=robot, gains=gains, rate=rate, time_unit=time_unit,
                        angle_unit=angle_unit, allow_duplicate_times=allow_duplicate_times, outliers=outliers, **rows)
    columns, column_gains, gain_field = split_gain_modifiers(columns, src)
    if column_gains is not None:
        if gains is not None:
            raise DataError(f"gains are given twice (in the column map and as {setting('gains')}); give them once", src)
        gains = column_gains
    if columns is not None:
        valid = [*FIELDS, "joint_names", *(EXTRA_KEYS if fmt is not None and fmt.items == "files" else ())]
        unknown = [k for k in columns if k not in valid]
        if unknown:
            raise DataError(f"unknown field(s) {unknown} in columns; valid fields: {valid}", src)
        if "joint_names" in columns and fmt is not None and not fmt.arrays:
            raise DataError(f"{setting('columns', {'joint_names': columns['joint_names']})} names an array of joint "
                            "names, which only array files hold (NPZ, HDF5, MATLAB); a table's joint names come from "
                            f"its header ({setting('columns', {'q': 'pos_{joint}'})})", src)
    check_time_unit(time_unit, rate, src)
    raw, what = _read_raw(fmt, path, src, columns, joint_names)
    warn_unused(src, raw.unused, what)
    n_hint = (len(joint_names) if joint_names is not None else len(raw.names) if raw.names is not None
              else len(robot.joint_names) if robot is not None else None)
    flipped = orient_samples(raw, n_hint, src) if fmt.arrays else []  # tables are sample-major
    opts = current_options()
    traj = _assemble(raw, src, joint_names, rate, robot, time_unit, opts.get("joint_order") or "names",
                     opts.get("time_from") or "stamps")
    if flipped:
        traj.units["layout"] = f"stored channels × samples, transposed: {', '.join(flipped)}"
    if gains is not None:
        traj = currents_to_torques(traj, gains, gain_field)
    if raw.extras:
        traj = traj.with_(extras={**traj.extras, **_sample_extras(raw.extras, src, len(traj))})
    if opts.get("base_rpy") and traj.base_q is not None:  # x y z + roll pitch yaw -> x y z + quaternion
        from .base_pose import pose_from_rpy  # imported on use: SciPy's rotations

        traj = traj.with_(base_q=pose_from_rpy(traj.base_q, src),
                          units={**traj.units, "base_q": "x y z + quaternion from logged roll pitch yaw (base_rpy)"})
    elif opts.get("base_rpy"):
        raise DataError(f"{setting('base_rpy', True)}: the log has no base pose; map it, e.g. "
                        f"{setting('columns', {'base_q': 'base_position,base_rpy'})}", src)
    traj = to_radians(traj, angle_unit, robot)
    return validate_trajectory(traj, robot, allow_duplicate_times=allow_duplicate_times, outliers=outliers, **rows)


def _read_raw(fmt, path: Path, src: str, columns, joint_names) -> tuple[RawLog, str]:
    """What the reader of ``path``'s format ``fmt`` (:mod:`.formats`) found, and what its unused items
    are (files, arrays, columns)."""
    if not (path.is_dir() or path.is_file()):
        raise DataError("not a regular file", src)
    if fmt is None:
        raise DataError(f"unsupported file type '{path.suffix}'; supported: {', '.join(SUPPORTED_EXTENSIONS)} "
                        "or a folder of per-signal text files", src)
    return fmt.read(path, columns, joint_names), fmt.items


_EXPECTED = {"contact": "n_feet", "contact_forces": "n_feet, 3 or 6", IMU_KEY: "3"}


def _contact_forces(val: Any, src: str, n: int) -> np.ndarray:
    """Measured contact wrenches as stored: (N, n_feet, 3|6) or flattened (N, n_feet·d)."""
    arr = as_float_array(val, "contact_forces", src)
    if arr.ndim not in (2, 3) or arr.shape[0] != n or (arr.ndim == 3 and arr.shape[2] not in (3, 6)):
        raise ShapeMismatchError(
            f"'contact_forces' has shape {arr.shape}; expected ({n}, n_feet, 3 or 6) or ({n}, n_feet·d) "
            "— one row per sample", src)
    return arr


def _sample_extras(found: dict[str, Any], src: str, n: int) -> dict[str, np.ndarray]:
    """The :data:`~sensorless.data.arrays.EXTRA_KEYS` arrays a reader found, checked (finite, N rows,
    flags 0/1, three accelerometer columns)."""
    out: dict[str, np.ndarray] = {}
    for key, val in found.items():
        arr = (_contact_forces(val, src, n) if key == "contact_forces"
               else as_float(val, src, key, allow_bool=key == "contact"))
        if arr.ndim < 2 or arr.shape[0] != n or (key == IMU_KEY and arr.shape != (n, 3)):
            raise DataError(f"'{key}' has shape {arr.shape}; expected ({n}, {_EXPECTED[key]}) — one row per sample", src)
        bad = np.argwhere(~np.isfinite(arr.reshape(n, -1)))
        if bad.size:
            raise DataError(f"'{key}' has a non-finite value at sample {bad[0][0]}", src)
        if key == "contact":
            odd = np.argwhere((arr != 0) & (arr != 1))
            if odd.size:
                raise DataError(f"'contact' flags must be 0 or 1; sample {odd[0][0]} has {arr[tuple(odd[0])]}", src)
            arr = arr.astype(bool)
        out[key] = arr
    return out


def write_npz(traj: Trajectory, path: str | Path) -> Path:
    """Write ``traj`` with the default keys (times, positions, velocities, accelerations,
    torques, joint_names, plus base_* and current/command when present)."""
    path = Path(path)
    data: dict[str, np.ndarray] = {"joint_names": np.array(traj.joint_names, dtype=str)}
    for field, key in _NPZ_KEYS.items():
        val = getattr(traj, field)
        if val is not None:
            data[key] = np.asarray(val, dtype=float)
    for field in ("base_q", "base_v", "base_a"):
        if getattr(traj, field) is not None:
            data[field] = getattr(traj, field)
    for key in JOINT_EXTRAS + EXTRA_KEYS:
        if key in traj.extras:
            data[key] = np.asarray(traj.extras[key], dtype=float)
    from ..io import write_npz_atomic  # hidden sibling + rename: a failed write leaves no partial file

    return write_npz_atomic(path, **data)


# ---- assembly ----------------------------------------------------------------------
JOINT_ORDERS = ("names", "model")
#: where the time axis comes from: the logged stamps, or the sample count at a rate (arrival-time stamps)
TIME_SOURCES = ("stamps", "rate")


def _from_rate(stamps, n: int, rate: float | None, time_unit, label: str, src: str) -> tuple[np.ndarray, str]:
    """t = k / rate for ``time_from="rate"``: ``rate`` if given, else the mean rate over the logged stamps' span
    (arrival times are late by a varying delay, but their long-run rate is the sampling rate)."""
    if rate is not None:
        rate = check_rate(rate, src)
        return np.arange(n) / rate, f"s (built from rate={rate:g} Hz; {setting('time_from', 'rate')})"
    if stamps is None:
        raise DataError(f"{setting('time_from', 'rate')} needs {setting('rate', placeholder='HZ')} or a time column to "
                        "take the mean rate from", src)
    s, _ = to_seconds(np.asarray(stamps, dtype=float).reshape(n, -1)[:, 0], time_unit, None, label, src)
    span = float(s[-1] - s[0])
    if not (np.isfinite(span) and span > 0):
        raise DataError(f"{setting('time_from', 'rate')}: the stamps of '{label}' span {span} s; give "
                        f"{setting('rate', placeholder='HZ')}", src)
    rate = (n - 1) / span
    return s[0] + np.arange(n) / rate, (f"s (uniform at the mean rate of the stamps, {rate:.6g} Hz over their "
                                        f"{span:.6g} s; {setting('time_from', 'rate')}: they are arrival times)")


def _model_order(raw: RawLog, robot: "Robot", n: int, src: str, joint_order: str) -> list[str]:
    """The robot's joint names for a log that names none of its ``n`` q columns: refused when the file holds
    text arrays (its joint names under a name of its own: the columns' order is then the log's, e.g. neck,
    torso, arms, legs, not the model's) unless ``joint_order="model"`` confirms the model's order."""
    if joint_order not in JOINT_ORDERS:
        raise DataError(f"{setting('joint_order')} must be one of {', '.join(JOINT_ORDERS)}, got {joint_order!r}", src)
    if raw.text and joint_order != "model":
        first = raw.text[0]
        raise DataError(
            f"'q' ('{raw.origin.get('q', 'q')}') has {n} columns, as many as robot '{robot.name}' has joints, but "
            f"their names were not read and the file holds text {short_list(raw.text, 8)}: if those are the joint "
            f"names, map them, {setting('columns', {'joint_names': first})}, and the columns are matched to the "
            f"model by name; if the columns follow the model's order ({', '.join(list(robot.joint_names)[:4])}, "
            f"...), confirm it with {setting('joint_order', 'model')}", src)
    return list(robot.joint_names)


def _assemble(raw: RawLog, src: str, joint_names: Sequence[str] | None, rate: float | None, robot: "Robot | None",
              time_unit: str | None, joint_order: str = "names", time_from: str = "stamps") -> Trajectory:
    arrays = raw.arrays
    for field, arr in arrays.items():
        if arr.ndim == 0:
            raise ShapeMismatchError(f"'{field}' is a single number (0-D), not one value per sample", src)
    q = arrays["q"]
    if q.ndim == 1:
        q = q[:, None]
    n = q.shape[1]
    if joint_names is not None:
        names = list(joint_names)
        if len(names) != n:
            raise ShapeMismatchError(f"joint_names has {len(names)} names but 'q' has {n} columns", src)
    elif raw.names is not None:
        if len(raw.names) != n:
            raise ShapeMismatchError(
                f"the file's joint names are {len(raw.names)} ({', '.join(map(repr, list(raw.names)[:8]))}) but 'q' "
                f"('{raw.origin.get('q', 'q')}') has {n} columns; store one name per q "
                f"column, or pick the q columns of those joints: {setting('columns', {'q': '...'})}", src)
        names = list(raw.names)
    elif robot is not None:
        if len(robot.joint_names) != n:
            raise ShapeMismatchError(
                f"'q' has {n} columns but robot '{robot.name}' has {len(robot.joint_names)} joints "
                f"{list(robot.joint_names)}; pick the q columns of those joints: "
                f"{setting('columns', {'q': '...'})}",
                src,
            )
        names = _model_order(raw, robot, n, src, joint_order)
    else:
        names = [f"joint_{i}" for i in range(n)]

    units: dict[str, str] = {}
    if time_from not in TIME_SOURCES:
        raise DataError(f"{setting('time_from')} must be one of {', '.join(TIME_SOURCES)}, got {time_from!r}", src)
    if time_from == "rate":  # arrival-time stamps: the samples are uniform, their stamps are not
        t, units["t"] = _from_rate(arrays.get("t"), q.shape[0], rate, time_unit, raw.origin.get("t", "t"), src)
    elif "t" in arrays:
        t = arrays["t"]
        if t.ndim == 2 and t.shape[1] == 1:
            t = t[:, 0]
        if t.ndim != 1:
            raise ShapeMismatchError(f"time must be 1-D, got shape {t.shape}", src)
        t, units["t"] = to_seconds(t, time_unit, rate, raw.origin.get("t", "t"), src)
    else:
        if time_unit == "tick":
            raise DataError(f"{setting('time_unit', 'tick')}: the log has no time/tick column (name it t, time or "
                            f"tick, or map it: {setting('columns', {'t': 'NAME'})})", src)
        if rate is None:
            raise DataError(f"no time column in {src}; give the sampling rate: {setting('rate', placeholder='HZ')}", src)
        rate = check_rate(rate, src)
        t = np.arange(q.shape[0]) / rate
        units["t"] = f"s (built from rate={rate:g} Hz)"
    extras = {k: arrays[k] for k in JOINT_EXTRAS if k in arrays}
    return Trajectory(
        t=t,
        q=q,
        joint_names=tuple(names),
        v=arrays.get("v"),
        a=arrays.get("a"),
        tau=arrays.get("tau"),
        base_q=arrays.get("base_q"),
        base_v=arrays.get("base_v"),
        base_a=arrays.get("base_a"),
        extras=extras,
        units=units,
        source=src,
    )

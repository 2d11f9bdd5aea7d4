"""Read logs (CSV/TXT, NPZ, Parquet, HDF5; ROS bags and MCAP via :mod:`.rosbag`) into a validated :class:`Trajectory`.

Fields are ``t, q, v, a, tau`` (plus ``current``, ``command`` → ``extras`` and
``base_q, base_v, base_a``). ``columns`` maps a field to where it is stored:

* NPZ / HDF5: an array key (HDF5: dataset name or path). Defaults: :data:`ALIASES`.
* CSV / Parquet: a list of column names (or 0-based indices), a pattern with
  ``"{joint}"`` (``"pos_{joint}"``) expanded over the joint names, or an index range
  ``"0:7"`` (the only option for a header-less CSV). With a header and no ``columns``
  the defaults are a time column ``t|time|times|timestamp`` and the header's naming
  convention (:func:`.tabular.detect_patterns`: ``q_{joint}``, ``pos_{joint}``,
  ``{joint}_position``, ``{joint}.velocity`` ...); the joint names come from the position
  columns.

Joint names: ``joint_names``, else names stored in the file (NPZ/HDF5 ``joint_names``
or the ``{joint}`` pattern), else ``robot.joint_names`` if the column count matches,
else ``joint_0..joint_{n-1}``. Time is kept as read (converted to seconds when
``time_unit`` is given); without a time field, ``t = arange(N) / rate``.

Currents: ``gains`` (or a ``':gain=...'`` suffix on the ``tau``/``current`` entry of
``columns``, e.g. ``{"tau": "i_{joint}:gain=10,10.7,9.6"}``; ``i_*`` = ``i_{joint}``)
turn logged motor currents into torques τ = K·i, see :mod:`sensorless.data.gains`.
"""

from __future__ import annotations

import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..errors import DataError, InputError, ShapeMismatchError, UnitsError
from ..io import check_input_file
from .containers import check_hdf5, check_npz
from .gains import currents_to_torques, split_gain_modifiers
from .imu import IMU_KEY
from .limits import current_options, prescan_text, read_options
from .tabular import Columns, _fields_from_frame, _read_csv, _read_parquet, _short
from .trajectory import Trajectory, as_float_array
from .validation import JOINT_EXTRAS, validate_trajectory

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["read_trajectory", "write_npz", "SUPPORTED_EXTENSIONS", "ALIASES", "FIELDS"]

SUPPORTED_EXTENSIONS = {
    ".csv": "csv",
    ".txt": "csv",
    ".npz": "npz",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".h5": "hdf5",
    ".hdf5": "hdf5",
}
FIELDS = ("t", "q", "v", "a", "tau", "current", "command", "base_q", "base_v", "base_a")
#: Default NPZ/HDF5 keys per field, first match wins.
ALIASES: dict[str, tuple[str, ...]] = {
    "t": ("times", "time", "t", "timestamp"),
    "q": ("positions", "q", "position", "joint_positions"),
    "v": ("velocities", "v", "qd", "velocity"),
    "a": ("accelerations", "a", "qdd", "acceleration"),
    "tau": ("torques", "tau", "effort", "efforts", "torque"),
    "current": ("current", "currents"),
    "command": ("command", "commands"),
    "base_q": ("base_q",),
    "base_v": ("base_v",),
    "base_a": ("base_a",),
}
_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: a log sampled this slowly [s] is not a dynamics log: its stamps are in another unit
_MAX_PLAUSIBLE_STEP = 1.0
#: Accepted sample rates [Hz] for logs without a time column (1 sample per 1000 s .. 10 MHz).
MIN_RATE, MAX_RATE = 1e-3, 1e7
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
    (:func:`~sensorless.data.validate_trajectory`).
    """
    with read_options(max_memory=max_memory, allow_external=allow_external, skip_bad=skip_bad,
                      skip_bad_rows=skip_bad_rows):
        return _read_trajectory(Path(path), joint_names, columns, rate, robot, time_unit, gains,
                                allow_duplicate_times, outliers, trim)


def _read_trajectory(path: Path, joint_names, columns, rate, robot, time_unit, gains, allow_duplicate_times,
                     outliers, trim=None) -> Trajectory:
    rows = {"trim": trim, "skip_bad_rows": bool(current_options().get("skip_bad_rows"))}
    src = str(path)
    if not path.exists():
        raise DataError("no such file", src)
    from .rosbag import is_rosbag, read_rosbag, rosbag_options

    if not path.is_dir():
        check_input_file(path, "log file")  # a FIFO or device would block or never end
    if is_rosbag(path):  # ROS 1/2 bag or MCAP: topics instead of columns (sensorless.data.rosbag)
        if gains is not None or rate is not None or time_unit is not None:
            raise DataError("gains, rate and time_unit do not apply to a ROS bag (its stamps are in seconds)", src)
        return read_rosbag(path, joint_names=joint_names, robot=robot, allow_duplicate_times=allow_duplicate_times,
                           outliers=outliers, **rows, **rosbag_options(columns, src))
    if not path.is_file():
        raise DataError("not a regular file", src)
    kind = SUPPORTED_EXTENSIONS.get(path.suffix.lower())
    if kind is None:
        raise DataError(
            f"unsupported file type '{path.suffix}'; supported: {', '.join(SUPPORTED_EXTENSIONS)}", src
        )
    columns, column_gains, gain_field = split_gain_modifiers(columns, src)
    if column_gains is not None:
        if gains is not None:
            raise DataError("gains are given twice (in the column map and as gains=...); give them once", src)
        gains = column_gains
    if columns is not None:
        unknown = [k for k in columns if k not in FIELDS]
        if unknown:
            raise DataError(f"unknown field(s) {unknown} in columns; valid fields: {list(FIELDS)}", src)
    if time_unit is not None and time_unit not in _TIME_SCALE:
        raise DataError(f"time_unit must be one of {list(_TIME_SCALE)}, got {time_unit!r}", src)

    if kind == "npz":
        raw, file_names = _read_npz(path, columns)
    elif kind == "hdf5":
        raw, file_names = _read_hdf5(path, columns)
    else:
        if kind == "csv":
            prescan_text(path, src)  # line length, field count and size bounded before pandas
        df, header = _read_csv(path) if kind == "csv" else (_read_parquet(path), True)
        raw, file_names = _fields_from_frame(df, src, columns, joint_names, header)
    traj = _assemble(raw, file_names, src, joint_names, rate, robot, time_unit)
    if gains is not None:
        traj = currents_to_torques(traj, gains, gain_field)
    if kind in ("npz", "hdf5"):
        extras = _sample_extras(path, kind, len(traj))
        if extras:
            traj = traj.with_(extras={**traj.extras, **extras})
    return validate_trajectory(traj, robot, allow_duplicate_times=allow_duplicate_times, outliers=outliers, **rows)


#: Per-sample contact data of legged-robot logs (NPZ/HDF5 keys): flags (N, n_feet) and
#: measured contact forces (N, n_feet, 3 or 6), both in the order of the contact frames.
CONTACT_KEYS = ("contact", "contact_forces")
#: Base IMU accelerometer reading, specific force in the base frame (N, 3) [m/s²].
IMU_KEYS = (IMU_KEY,)
_EXPECTED = {"contact": "n_feet", "contact_forces": "n_feet, 3 or 6", "imu_acc": "3"}


def _contact_forces(val: Any, src: str, n: int) -> np.ndarray:
    """Measured contact wrenches as stored: (N, n_feet, 3|6) or flattened (N, n_feet·d)."""
    arr = as_float_array(val, "contact_forces", src)
    if arr.ndim not in (2, 3) or arr.shape[0] != n or (arr.ndim == 3 and arr.shape[2] not in (3, 6)):
        raise ShapeMismatchError(
            f"'contact_forces' has shape {arr.shape}; expected ({n}, n_feet, 3 or 6) or ({n}, n_feet·d) "
            "— one row per sample", src)
    return arr


def _sample_extras(path: Path, kind: str, n: int) -> dict[str, np.ndarray]:
    """Read :data:`CONTACT_KEYS` and :data:`IMU_KEYS` if present, checked (finite, N rows,
    flags 0/1, three accelerometer columns)."""
    src = str(path)
    out: dict[str, np.ndarray] = {}
    try:
        if kind == "npz":
            with np.load(path, allow_pickle=False) as z:
                found = {k: z[k] for k in CONTACT_KEYS + IMU_KEYS if k in z.files}
        else:
            import h5py

            with h5py.File(path, "r") as f:
                found = {k: f[k][()] for k in CONTACT_KEYS + IMU_KEYS if k in f}
    except _READ_ERRORS as exc:
        raise DataError(f"cannot read contact/IMU arrays ({_one_line(exc)})", src) from None
    for key, val in found.items():
        arr = (_contact_forces(val, src, n) if key == "contact_forces"
               else _as_float(val, src, key, allow_bool=key == "contact"))
        if arr.ndim < 2 or arr.shape[0] != n or (key in IMU_KEYS and arr.shape != (n, 3)):
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
    for key in JOINT_EXTRAS + CONTACT_KEYS + IMU_KEYS:
        if key in traj.extras:
            data[key] = np.asarray(traj.extras[key], dtype=float)
    from ..io import write_npz_atomic  # hidden sibling + rename: a failed write leaves no partial file

    return write_npz_atomic(path, **data)


# ---- NPZ / HDF5 ------------------------------------------------------------------
def _pick_key(field: str, keys: list[str], columns: Columns | None, src: str, base=lambda k: k) -> str | None:
    """The stored key for ``field``: the ``columns`` override, else the first alias present."""
    if columns is not None and field in columns:
        key = columns[field]
        if not isinstance(key, str):
            raise DataError(f"columns['{field}'] must be an array key (str) for this format, got {key!r}", src)
        key = key.lstrip("/")
        if key in keys:
            return key
        hits = [k for k in keys if base(k) == key]
        if len(hits) == 1:
            return hits[0]
        raise DataError(f"no array '{key}' (for '{field}'); available: {_short(keys)}", src)
    for alias in ALIASES[field]:
        for match in (lambda k: k == alias, lambda k: k.lower() == alias):
            hits = [k for k in keys if match(base(k))]
            if hits:
                depth = min(h.count("/") for h in hits)
                top = [h for h in hits if h.count("/") == depth]
                if len(top) > 1:
                    raise DataError(
                        f"ambiguous '{field}': several arrays named '{alias}' ({top}); "
                        f"pass columns={{'{field}': <path>}}",
                        src,
                    )
                return top[0]
    return None


#: What a corrupt NPZ/HDF5 member can raise on read (zlib, zip, h5py/HDF5 and numpy errors).
#: numpy parses a corrupt .npy header with tokenize/ast (TokenError, SyntaxError) and may try to
#: allocate what a corrupt header declares (MemoryError).
_READ_ERRORS = (OSError, ValueError, EOFError, KeyError, RuntimeError, TypeError, IndexError, AttributeError,
                OverflowError, MemoryError, SyntaxError, tokenize.TokenError, zipfile.BadZipFile, zlib.error)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:300]}" if text else type(exc).__name__


def _as_float(arr: Any, src: str, key: str, allow_bool: bool = False, max_dim: int = 2) -> np.ndarray:
    out = as_float_array(arr, key, src, allow_bool=allow_bool)
    if out.ndim > max_dim:
        raise ShapeMismatchError(f"array '{key}' has shape {out.shape}; expected 1-D or 2-D", src)
    return out


def _names(raw: Any, src: str) -> list[str]:
    """Joint names stored in a file: a 1-D array of strings (bytes are decoded)."""
    arr = np.atleast_1d(np.asarray(raw))
    if arr.ndim != 1 or arr.dtype.kind not in "USO":
        raise DataError(f"'joint_names' must be a 1-D array of strings, got dtype {arr.dtype} shape {arr.shape}", src)
    try:
        return [n.decode() if isinstance(n, bytes) else str(n) for n in arr]
    except UnicodeDecodeError:
        raise DataError("'joint_names' are not valid UTF-8", src) from None


def _missing_q(keys: list[str], src: str) -> DataError:
    return DataError(
        f"no joint positions found (looked for {list(ALIASES['q'])}); available: {_short(keys)}; "
        "pass columns={'q': <key>}",
        src,
    )


def _read_npz(path: Path, columns: Columns | None) -> tuple[dict[str, np.ndarray], list[str] | None]:
    src = str(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except _READ_ERRORS as exc:
        raise DataError(f"not a readable NPZ archive ({_one_line(exc)})", src) from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise DataError("holds a single array (.npy), not an NPZ archive of named arrays", src)
    with archive as z:
        keys = list(z.files)
        raw: dict[str, np.ndarray] = {}
        picked = {f: k for f in FIELDS if (k := _pick_key(f, keys, columns, src)) is not None}
        check_npz(path, src, [*picked.values(), *(k for k in CONTACT_KEYS + IMU_KEYS if k in keys)])
        try:
            for field, key in picked.items():
                raw[field] = _as_float(z[key], src, key)
            names = _names(z["joint_names"], src) if "joint_names" in keys else None
        except (DataError, InputError):
            raise
        except _READ_ERRORS as exc:  # pickled/object or corrupt member (zlib.error, BadZipFile...)
            raise DataError(f"cannot read an array from the NPZ archive ({_one_line(exc)})", src) from None
    if "q" not in raw:
        raise _missing_q(keys, src)
    return raw, names


def _read_hdf5(path: Path, columns: Columns | None) -> tuple[dict[str, np.ndarray], list[str] | None]:
    import h5py

    src = str(path)
    try:
        f = h5py.File(path, "r")
    except _READ_ERRORS as exc:
        raise DataError(f"not a readable HDF5 file ({_one_line(exc)})", src) from None
    try:
        return _hdf5_fields(f, src, columns)
    except (DataError, InputError):
        raise
    except _READ_ERRORS as exc:  # corrupt dataset, bad link, undecodable names...
        raise DataError(f"cannot read a dataset from the HDF5 file ({_one_line(exc)})", src) from None
    finally:
        f.close()


def _hdf5_fields(f, src: str, columns: Columns | None) -> tuple[dict[str, np.ndarray], list[str] | None]:
    import h5py

    keys: list[str] = []
    f.visititems(lambda name, obj: keys.append(name) if isinstance(obj, h5py.Dataset) else None)
    base = lambda k: k.rsplit("/", 1)[-1]  # noqa: E731
    raw: dict[str, np.ndarray] = {}
    picked = {fd: k for fd in FIELDS if (k := _pick_key(fd, keys, columns, src, base)) is not None}
    check_hdf5(f, [*picked.values(), *(k for k in CONTACT_KEYS + IMU_KEYS + ("joint_names",) if k in keys)], src)
    for field, key in picked.items():
        raw[field] = _as_float(f[key][()], src, key)
    names = None
    if "joint_names" in keys:
        names = f["joint_names"][()]
    elif "joint_names" in f.attrs:
        names = f.attrs["joint_names"]
    if names is not None:
        names = _names(names, src)
    if "q" not in raw:
        raise _missing_q(keys, src)
    return raw, names


# ---- assembly ----------------------------------------------------------------------
def _epoch_unit(t: np.ndarray, src: str) -> str:
    """The unit of a time column given without one: Unix-epoch stamps in ms, µs or ns (ROS's
    ``%time``) are told apart by magnitude (seconds since 1970 stay below 1e11 until the year
    5138) and converted; relative stamps whose median step is over a second raise UnitsError."""
    finite = t[np.isfinite(t)]
    if finite.size < 2:
        return "s"
    start = float(np.abs(finite[0]))
    for unit, low in (("ns", 1e17), ("us", 1e14), ("ms", 1e11)):
        if start >= low:
            return unit
    step = float(np.median(np.diff(finite)))
    if finite.size >= 20 and step > _MAX_PLAUSIBLE_STEP:
        guess = next((u for u in ("ms", "us", "ns") if step * _TIME_SCALE[u] <= _MAX_PLAUSIBLE_STEP), "ns")
        raise UnitsError(
            f"the time column steps by {step:.6g} (median): a {1 / step:.3g} Hz log, too slow for dynamics; the stamps "
            f"look like {guess} (then {1 / (step * _TIME_SCALE[guess]):.4g} Hz). Store seconds, or pass "
            f"time_unit='{guess}' to read_trajectory (command line: --time-unit {guess})", src)
    return "s"


def _assemble(
    raw: dict[str, np.ndarray],
    file_names: list[str] | None,
    src: str,
    joint_names: Sequence[str] | None,
    rate: float | None,
    robot: "Robot | None",
    time_unit: str | None,
) -> Trajectory:
    for field, arr in raw.items():
        if arr.ndim == 0:
            raise ShapeMismatchError(f"'{field}' is a single number (0-D), not one value per sample", src)
    q = raw["q"]
    if q.ndim == 1:
        q = q[:, None]
    n = q.shape[1]
    if joint_names is not None:
        names = list(joint_names)
        if len(names) != n:
            raise ShapeMismatchError(f"joint_names has {len(names)} names but 'q' has {n} columns", src)
    elif file_names is not None:
        if len(file_names) != n:
            raise ShapeMismatchError(
                f"the file's joint_names has {len(file_names)} names but 'q' has {n} columns; "
                "pass joint_names=[...] in column order", src)
        names = list(file_names)
    elif robot is not None:
        if len(robot.joint_names) != n:
            raise ShapeMismatchError(
                f"'q' has {n} columns but robot '{robot.name}' has {len(robot.joint_names)} joints "
                f"{list(robot.joint_names)}; pass joint_names=[...] in column order",
                src,
            )
        names = list(robot.joint_names)
    else:
        names = [f"joint_{i}" for i in range(n)]

    units: dict[str, str] = {}
    if "t" in raw:
        t = raw["t"]
        if t.ndim == 2 and t.shape[1] == 1:
            t = t[:, 0]
        if t.ndim != 1:
            raise ShapeMismatchError(f"time must be 1-D, got shape {t.shape}", src)
        if time_unit is None:
            time_unit = _epoch_unit(t, src)
            if time_unit != "s":
                units["t"] = f"s (converted from {time_unit}: epoch stamps of that magnitude)"
        if time_unit is not None:
            t = t * _TIME_SCALE[time_unit]
        units.setdefault("t", "s" if time_unit in (None, "s") else f"s (converted from {time_unit})")
    else:
        if rate is None:
            raise DataError(f"no time column in {src}; pass rate=... (Hz)", src)
        if not isinstance(rate, (int, float, np.integer, np.floating)) or not MIN_RATE <= rate <= MAX_RATE:
            raise DataError(f"rate must be a number of Hz in [{MIN_RATE:g}, {MAX_RATE:g}], got {rate!r}", src)
        t = np.arange(q.shape[0]) / float(rate)
        units["t"] = f"s (built from rate={rate:g} Hz)"
    extras = {k: raw[k] for k in JOINT_EXTRAS if k in raw}
    return Trajectory(
        t=t,
        q=q,
        joint_names=tuple(names),
        v=raw.get("v"),
        a=raw.get("a"),
        tau=raw.get("tau"),
        base_q=raw.get("base_q"),
        base_v=raw.get("base_v"),
        base_a=raw.get("base_a"),
        extras=extras,
        units=units,
        source=src,
    )

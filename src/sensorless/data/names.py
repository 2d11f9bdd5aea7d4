"""The names a log's arrays, columns and files may have: one table for every reader.

:data:`FIELD_NAMES` lists, per Trajectory field, the names a reader recognises without a
``--columns`` map: NPZ keys, HDF5/MAT dataset or variable names (the last path component,
the shallowest wins), CSV/Parquet/text header words (``q_{joint}``, ``{joint}.velocity``;
:mod:`.tabular`) and the files of a per-signal folder (``q.dat``, ``dq.dat``; :mod:`.textlog`).
Names compare case-insensitively and without ``_``/``-`` (``jointPositions`` =
``joint_positions``). The first name present wins; every array, column or file a reader does
not use is named in one :class:`~sensorless.errors.DataWarning` per file (:func:`warn_unused`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from ..errors import DataError, DataWarning, setting, did_you_mean

__all__ = ["FIELD_NAMES", "TICK_NAMES", "JOINT_NAME_KEYS", "RawLog", "normalise", "field_of", "is_tick_name", "pick_key",
           "warn_unused", "short_list"]

#: field -> recognised names, first = the default header word (``q_{joint}``) where it is one
FIELD_NAMES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "times", "timestamp", "timestamps", "stamp", "%time", "__time"),
    "q": ("q", "pos", "position", "positions", "joint_positions", "angle"),
    "v": ("v", "dq", "qd", "qdot", "vel", "velocity", "velocities", "joint_velocities"),
    "a": ("a", "ddq", "qdd", "qddot", "acc", "acceleration", "accelerations", "joint_accelerations"),
    "tau": ("tau", "effort", "efforts", "torque", "torques", "eff", "trq", "joint_torques"),
    "current": ("current", "currents", "i", "cur", "curr"),
    "command": ("command", "commands", "cmd", "q_cmd"),
    "tau_out": ("tau_out", "output_torque", "load_torque", "tau_load"),
    "q_motor": ("q_motor", "motor_position", "motor_angle"),
    "base_q": ("base_q",),
    "base_v": ("base_v",),
    "base_a": ("base_a",),
}
#: names of a time column that counts controller ticks (read with ``--time-unit tick --rate HZ``)
TICK_NAMES = ("tick", "ticks", "tick_count", "cycle", "cycles", "counter")
#: names of the joint-name array (NPZ/HDF5/MAT: strings, in column order)
JOINT_NAME_KEYS = ("joint_names", "names")


def normalise(name: str) -> str:
    """``'Joint_Positions'`` -> ``'jointpositions'`` (case, ``_``, ``-`` and spaces ignored)."""
    return "".join(ch for ch in str(name).lower() if ch not in "_- ")


_FIELD_OF = {normalise(n): f for f, names in FIELD_NAMES.items() for n in names}
_FIELD_OF.update({normalise(n): "t" for n in TICK_NAMES})


def field_of(name: str) -> str | None:
    """The field a name stands for (``'dq'`` -> ``'v'``, ``'tick'`` -> ``'t'``), else None."""
    return _FIELD_OF.get(normalise(name))


def is_tick_name(name: str) -> bool:
    return normalise(name) in {normalise(n) for n in TICK_NAMES}


def short_list(items: Sequence, limit: int = 40) -> str:
    items = list(items)
    return str(items if len(items) <= limit else items[:limit] + [f"... ({len(items) - limit} more)"])


@dataclass
class RawLog:
    """What a reader found: ``arrays`` per field (as stored, before orientation and units),
    joint ``names`` stored in the file, ``origin`` (field -> the array/column it came from),
    per-sample ``extras`` (contact flags/forces, IMU), the ``unused`` arrays/columns, and which of those
    hold ``text`` (joint names under a name of the file's own: ``--columns joint_names=NAME``)."""

    arrays: dict[str, np.ndarray]
    names: list[str] | None = None
    origin: dict[str, str] = field(default_factory=dict)
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    unused: list[str] = field(default_factory=list)
    text: list[str] = field(default_factory=list)


def pick_key(fld: str, keys: Sequence[str], columns: Mapping | None, src: str,
             base: Callable[[str], str] = lambda k: k, names: Sequence[str] | None = None) -> str | None:
    """The stored key for ``fld``: the ``columns`` entry (a full path, or a last component
    that is unique), else the first of ``names`` (default :data:`FIELD_NAMES`) present,
    compared by :func:`normalise` on the last path component; the shallowest match wins and
    two at the same depth are an error."""
    if columns is not None and fld in columns:
        key = columns[fld]
        if not isinstance(key, str):
            raise DataError(f"{setting('columns', {fld: '...'})} must name one array for this format (e.g. "
                            f"{setting('columns', {fld: f'data/{fld}'})}), got {key!r}", src)
        key = key.strip().lstrip("/")
        if key in keys:
            return key
        hits = [k for k in keys if base(k) == key] or [k for k in keys if normalise(k) == normalise(key)]
        if len(hits) == 1:
            return hits[0]
        close = "" if hits else did_you_mean(key, keys)
        raise DataError(f"no array '{key}' (for '{fld}'" + (f"; several end in it: {hits}" if hits else "")
                        + f"); {close + ' ' if close else ''}available: {short_list(keys)}", src)
    for alias in (FIELD_NAMES[fld] if names is None else names):
        hits = [k for k in keys if normalise(base(k)) == normalise(alias)]
        if hits:
            depth = min(h.count("/") for h in hits)
            top = [h for h in hits if h.count("/") == depth]
            if len(top) > 1:
                raise DataError(f"ambiguous '{fld}': several arrays named '{alias}' ({top}); "
                                f"say which with {setting('columns', {fld: top[0]})}", src)
            return top[0]
    return None


def warn_unused(src: str, unused: Sequence[str], what: str = "arrays") -> None:
    """One DataWarning naming what a reader did not use (nothing when ``unused`` is empty)."""
    if not unused:
        return
    shown = ", ".join(f"'{u}'" for u in list(unused)[:20]) + (f" ... ({len(unused) - 20} more)" if len(unused) > 20
                                                            else "")
    warnings.warn(f"{src}: {what} not used: {shown} (no field has such a name; recognised names: docs/logs.md; "
                  f"map one with {setting('columns', {'FIELD': 'NAME'})})", DataWarning, stacklevel=3)

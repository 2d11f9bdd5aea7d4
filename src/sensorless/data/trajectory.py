"""Trajectory: one logged (or simulated) run of a robot.

Arrays are sample-major: ``q[i, j]`` is joint ``joint_names[j]`` at time ``t[i]``.
Units are SI (rad, m, rad/s, N·m, N); ``units`` records what the file said.
The base of a floating-base robot is optional: pose ``[x y z qx qy qz qw]``,
twist and its derivative in the base frame (Pinocchio's LOCAL convention).
``provenance`` says where each signal came from (``{"v": "logged", "a": "derived: ..."}``,
drive gains, timing and resampling); :func:`sensorless.data.prepare` fills it in.
Per-sample ``extras`` of legged robots: ``contact`` flags (N, n_feet) and measured
``contact_forces`` (N, n_feet, 3 | 6) [f; τ] in world axes at the contact frames, in the
order of the contact frames (``take``/``concatenate`` slice them along samples).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Iterator

import numpy as np

from ..errors import DataError

__all__ = ["Trajectory", "as_float_array"]

_PER_SAMPLE = ("q", "v", "a", "tau", "base_q", "base_v", "base_a")


@dataclass
class Trajectory:
    t: np.ndarray
    q: np.ndarray
    joint_names: tuple[str, ...]
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    tau: np.ndarray | None = None
    base_q: np.ndarray | None = None
    base_v: np.ndarray | None = None
    base_a: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    source: str = "<array>"
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.joint_names = tuple(self.joint_names)
        self.t = as_float_array(self.t, "t", self.source)
        for name in _PER_SAMPLE:
            val = getattr(self, name)
            if val is not None:
                setattr(self, name, as_float_array(val, name, self.source))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def dt(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t))) if len(self) > 1 else float("nan")

    @property
    def rate(self) -> float:
        """Median sample rate [Hz]."""
        return 1.0 / self.dt

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self) else 0.0

    def take(self, index: slice | np.ndarray) -> "Trajectory":
        """Samples selected by a slice, an index array or a boolean mask."""
        kw = {n: (None if getattr(self, n) is None else getattr(self, n)[index]) for n in _PER_SAMPLE}
        extras = {k: v[index] for k, v in self.extras.items()}
        return replace(self, t=self.t[index], extras=extras, **kw)

    def chunks(self, size: int) -> Iterator["Trajectory"]:
        """Consecutive pieces of at most ``size`` samples (views, no copy)."""
        for start in range(0, len(self), size):
            yield self.take(slice(start, start + size))

    def with_(self, **changes) -> "Trajectory":
        """A copy with some fields replaced (dataclasses.replace)."""
        return replace(self, **changes)

    def select_joints(self, names: tuple[str, ...] | list[str]) -> "Trajectory":
        """The same samples with joint columns reordered/subset to ``names``."""
        idx = [self.joint_names.index(n) for n in names]
        kw = {n: (None if getattr(self, n) is None else getattr(self, n)[:, idx]) for n in ("q", "v", "a", "tau")}
        return replace(self, joint_names=tuple(names), **kw)

    @staticmethod
    def concatenate(parts: list["Trajectory"]) -> "Trajectory":
        """Join trajectories with the same joints (time is kept as is)."""
        first = parts[0]
        kw = {}
        for n in _PER_SAMPLE:
            vals = [getattr(p, n) for p in parts]
            kw[n] = None if any(v is None for v in vals) else np.concatenate(vals)
        extras = {k: np.concatenate([p.extras[k] for p in parts]) for k in first.extras if all(k in p.extras for p in parts)}
        return replace(first, t=np.concatenate([p.t for p in parts]), extras=extras, **kw)


def as_float_array(val, name: str, source: str | None = None, allow_bool: bool = False) -> np.ndarray:
    """``val`` as a float array, or DataError for values that are not real numbers.

    Integers and floats convert; booleans (unless ``allow_bool``), complex numbers,
    datetimes/timedeltas, strings and objects that are not numbers are refused rather
    than silently cast (a complex cast would drop the imaginary part, a bool one is a flag).
    """
    arr = val if isinstance(val, np.ndarray) else None
    if arr is None:
        try:
            arr = np.asarray(val)
        except (TypeError, ValueError) as exc:  # ragged nested lists
            raise DataError(f"array '{name}' is not numeric ({str(exc).splitlines()[0]})", source) from None
    kind = arr.dtype.kind
    ok = "iuf" + ("b" if allow_bool else "")
    if kind not in ok + "O":
        what = {"b": "boolean", "c": "complex", "M": "datetime", "m": "timedelta", "U": "text", "S": "bytes",
                "V": "structured"}.get(kind, str(arr.dtype))
        raise DataError(f"array '{name}' is not numeric: {what} values (dtype {arr.dtype}); expected real numbers", source)
    try:
        out = np.asarray(arr, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise DataError(f"array '{name}' is not numeric: values that are not real numbers (dtype {arr.dtype})", source) from None
    return out

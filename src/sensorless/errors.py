"""Typed errors. Every message names the file, column, joint or sample at fault.

All derive from :class:`SensorlessError`, which the CLI turns into one line and a
non-zero exit code.

A message that suggests a configuration change names the setting by its field, written with
:func:`setting` as `` `field` `` or `` `field=value` `` (the keyword of the Python call, e.g.
`` `rate=HZ` ``, `` `lock_joints=['a', 'b']` ``). A Python caller reads the keyword; the CLI
rewrites each such field into its own option (``--rate HZ``, ``--lock a --lock b``), so one
message serves both. :func:`settings_in` lists the settings a message names; :func:`did_you_mean`
words the nearest known names for an unknown one.
"""

from __future__ import annotations

import difflib
import re
from typing import Iterable

__all__ = [
    "SensorlessError",
    "RobotModelError",
    "UntrustedModelError",
    "DataError",
    "NonFiniteError",
    "ShapeMismatchError",
    "JointNameError",
    "TimestampError",
    "UnitsError",
    "ExcitationError",
    "SolverError",
    "PhysicalConsistencyError",
    "PlausibilityError",
    "OutputError",
    "InputError",
    "ParameterError",
    "OptionError",
    "OutlierError",
    "TooFewSamplesError",
    "DistributedError",
    "SimulationError",
    "SensorlessWarning",
    "IdentifiabilityWarning",
    "DataWarning",
    "RobotModelWarning",
    "did_you_mean",
    "python_only",
    "setting",
    "settings_in",
]

_NO_VALUE = object()
SETTING_PATTERN = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)?)(?:=([^`]*))?`")
"""A setting named in a message: `` `field` ``, `` `field=value` `` or a run configuration's `` `group.field` ``
(``solver.gamma``, :mod:`sensorless.run.config`) (group 1: field, group 2: value text)."""


def setting(field: str, value: object = _NO_VALUE, *, placeholder: str | None = None) -> str:
    """The configuration setting ``field`` as a message names it: `` `field` ``, `` `field=value` ``
    (``repr(value)``) or `` `field=PLACEHOLDER` `` (e.g. ``HZ``, ``FILE``: a value to fill in)."""
    if placeholder is not None:
        return f"`{field}={placeholder}`"
    return f"`{field}`" if value is _NO_VALUE else f"`{field}={value!r}`"


PYTHON_ONLY_PATTERN = re.compile(r" ?\(in Python: [^()]*(?:\([^()]*\)[^()]*)*\)")
"""A note only a Python caller can act on (:func:`python_only`); the CLI leaves it out."""


def python_only(note: str) -> str:
    """``" (in Python: note)"``: advice about a call only a Python caller makes (the CLI leaves it out)."""
    return f" (in Python: {note})"


def settings_in(message: object) -> list[tuple[str, str | None]]:
    """(field, value text or None) of every setting ``message`` names (written by :func:`setting`)."""
    return [(m.group(1), m.group(2)) for m in SETTING_PATTERN.finditer(str(message))]


def did_you_mean(name: object, known: Iterable[object], n: int = 3, cutoff: float = 0.6) -> str:
    """``"did you mean 'a' or 'b'?"`` for the known names closest to ``name`` (difflib ratio ≥
    ``cutoff``, case-insensitive), or ``""`` when none is close. One wording for robots, frames,
    joints and columns."""
    names = [str(k) for k in known]
    lower: dict[str, str] = {}
    for k in names:
        lower.setdefault(k.lower(), k)
    close = difflib.get_close_matches(str(name).lower(), list(lower), n=n, cutoff=cutoff)
    return f"did you mean {' or '.join(repr(lower[c]) for c in close)}?" if close else ""


class SensorlessError(Exception):
    """Base class of every error this package raises on purpose."""

    @property
    def settings(self) -> list[tuple[str, str | None]]:
        """The settings the message suggests changing (:func:`settings_in`)."""
        return settings_in(self)


class RobotModelError(SensorlessError):
    """A robot model cannot be loaded, or a joint/frame/body name is unknown."""


class UntrustedModelError(RobotModelError):
    """A robot description that could run code when loaded (a xacro file), refused without consent."""


class DataError(SensorlessError, ValueError):
    """A log is unusable. ``source`` is the file (or "<array>") it came from."""

    def __init__(self, message: str, source: str | None = None) -> None:
        self.source = source
        super().__init__(f"{source}: {message}" if source else message)


class NonFiniteError(DataError):
    """NaN or inf values in a signal."""


class ShapeMismatchError(DataError):
    """Arrays whose sample count or column count disagree."""


class JointNameError(DataError):
    """Joint names in a log that the robot does not have (or is missing)."""


class TimestampError(DataError):
    """Time that is not strictly increasing (non-monotonic or duplicate stamps)."""


class UnitsError(DataError):
    """Values whose magnitude suggests the wrong unit (e.g. degrees for radians)."""


class OutlierError(DataError):
    """Gross outliers (glitched samples) in a signal; see :mod:`sensorless.data.outliers`."""


class ExcitationError(SensorlessError):
    """Too few samples, or a trajectory that does not excite the parameters (rank)."""


class TooFewSamplesError(DataError, ExcitationError):
    """Fewer samples than required (both a DataError and an ExcitationError)."""


class DistributedError(SensorlessError):
    """The Dask run could not complete: scheduler unreachable, dask missing, a worker lost too often."""


class SimulationError(SensorlessError, ValueError):
    """Invalid simulation settings, an infeasible scenario plan, or a fall with ``on_fall="raise"``."""


class SolverError(SensorlessError):
    """A numerical solve failed, was infeasible or inaccurate."""


class PhysicalConsistencyError(SensorlessError, ValueError):
    """Inertial parameters that no real body can have (e.g. mass <= 0, indefinite pseudo-inertia)."""


class PlausibilityError(SensorlessError, ValueError):
    """An identified model with an implausible quantity (non-finite, a body heavier than the whole
    prior robot, a CoM far outside its body, a determined total mass far from the prior's)."""


class OutputError(SensorlessError):
    """An output path that cannot be written, or must not be replaced (not a sensorless output,
    the working or home directory, a directory holding the inputs, another run writing it)."""
class InputError(SensorlessError, ValueError):
    """An input path that must not be read: missing, a FIFO/device/socket instead of a regular file,
    larger than the configured limit, or pointing outside the folder it must stay in."""
class ParameterError(SensorlessError, ValueError):
    """A parameter vector, parameter file or model description with the wrong size, keys or values."""
class OptionError(SensorlessError, ValueError):
    """An option (command line or keyword argument) with an invalid value."""
class SensorlessWarning(UserWarning):
    """Base class of the warnings this package issues (the CLI prints each on one line)."""
class IdentifiabilityWarning(SensorlessWarning):
    """Identified parameters that the data determine poorly (large relative standard deviation)."""
class DataWarning(SensorlessWarning):
    """A log was altered on request (e.g. outlier samples dropped) or looks suspicious."""
class RobotModelWarning(SensorlessWarning):
    """A robot model that loads but looks wrong (e.g. an inertia that no real body has)."""

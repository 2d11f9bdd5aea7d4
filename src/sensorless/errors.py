"""Typed errors. Every message names the file, column, joint or sample at fault.

All derive from :class:`SensorlessError`, which the CLI turns into one line and a
non-zero exit code.
"""

from __future__ import annotations

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
]


class SensorlessError(Exception):
    """Base class of every error this package raises on purpose."""


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

"""Moved to :mod:`sensorless.benchmarks.lmi`; this name remains for old imports (``sensorless benchmark lmi``)."""

from ..benchmarks.lmi import bench_lmi, random_state_equations

__all__ = ["bench_lmi", "random_state_equations"]

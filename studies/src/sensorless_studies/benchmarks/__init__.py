"""Speed and scale benchmarks (JSON-able dicts; run through ``sensorless benchmark ...``).

This is the top layer next to ``experiments``: benchmarks may import anything below them
(simulation, identification, actuator), and no library module imports them.
"""

from .actuator import benchmark_asymmetric_fit
from .lmi import bench_lmi, random_state_equations
from .simulation import benchmark_simulation

__all__ = ["bench_lmi", "benchmark_asymmetric_fit", "benchmark_simulation", "random_state_equations"]

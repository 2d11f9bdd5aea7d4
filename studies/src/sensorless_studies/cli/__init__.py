"""The studies' commands, added to ``sensorless`` through the entry points of group ``sensorless.commands``
(studies/pyproject.toml): ``sensorless benchmark …``, ``sensorless experiment …``, ``sensorless example``,
``sensorless demo``. Importing this package registers every command (no NumPy: each command imports
what it runs when it runs)."""

from . import bench, bench_monitoring, contact_id, hybrid_force, psm, torque_control  # noqa: F401  (register their commands)
from .common import bench_app, experiment_app
from .demo import demo_app
from .example import example_app

__all__ = ["benchmark_app", "experiment_app", "example_app", "demo_app"]

#: ``sensorless benchmark``
benchmark_app = bench_app

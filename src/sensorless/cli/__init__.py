"""Command-line interface (typer). Every SensorlessError becomes one red line and exit code 2.

Each command group lives in its own module and registers itself on :data:`app`.
"""

from . import contact_id, core, drive_gains, excite, hybrid_force, monitor, payload, torque_control  # noqa: F401  (each module registers its commands)
from .common import app, atomic_outdir, guarded

__all__ = ["app", "atomic_outdir", "guarded", "main"]


def main() -> None:  # pragma: no cover
    app()

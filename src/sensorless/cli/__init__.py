"""Command-line interface (typer). Every SensorlessError becomes one red line and exit code 2.

Each command group lives in its own module and registers itself on :data:`app`; the studies package
(sensorless-studies: `example`, `experiment`, `benchmark`, `demo`) adds its commands through entry points
(:mod:`.plugins`).
"""

from . import identify, predict, drive_gains, export, excite, frames, friction, hybrid_force, monitor, payload, stream  # noqa: F401  (each module registers its commands)
import typer

from .common import app, atomic_outdir, guarded

__all__ = ["app", "atomic_outdir", "guarded", "main"]


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"sensorless {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="print the version and exit"),
) -> None:
    """Dynamic models for robots without torque or force sensors."""


def main() -> None:  # pragma: no cover
    app()

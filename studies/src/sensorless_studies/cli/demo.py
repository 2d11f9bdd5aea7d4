"""`sensorless demo`: the end-to-end example on a simulated Panda (:mod:`sensorless_studies.demo`)."""

from __future__ import annotations

from pathlib import Path

import typer

from sensorless.cli.common import atomic_outdir, force_option, guarded
from sensorless.cli.console import console

__all__ = ["demo", "demo_app"]

#: `sensorless demo` (one command)
demo_app = typer.Typer(add_completion=False)


@demo_app.command()
@guarded
def demo(
    out: Path = typer.Option(Path("demo_output"), help="output directory"),
    seed: int = typer.Option(0, help="random seed"),
    force: bool = force_option(),
) -> None:
    """End-to-end example on a simulated Panda: excite, identify, validate, export."""
    from ..demo import run_demo

    with atomic_outdir(out, force=force) as tmp:
        run_demo(tmp, seed=seed, console=console)
    console.print(f"wrote {out}/")

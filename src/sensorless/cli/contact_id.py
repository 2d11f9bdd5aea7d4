"""`sensorless experiment contact-id`: the legged-robot identification study."""

from __future__ import annotations

from pathlib import Path

import typer

from .common import atomic_outdir, console, experiment_app, guarded


@experiment_app.command("contact-id")
@guarded
def contact_id(
    out: Path = typer.Option(Path("results/contact_id"), help="output directory"),
    quick: bool = typer.Option(False, help="small version (a few minutes): up to 10^4 samples, small MLP"),
    seed: int = typer.Option(0),
    acceleration: str = typer.Option("savgol", help="savgol (estimated from logged v, realistic) | simulator (exact)"),
    coulomb_smoothing: float = typer.Option(0.02, help="ε [rad/s] of the Coulomb term tanh(v/ε); 0 = sgn(v)"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """LMI vs SVD vs MLP on simulated Solo12 logs: sample efficiency, OOD trot and jump, parameter errors."""
    from ..errors import SensorlessError
    from ..experiments.contact_id import run

    if acceleration not in ("savgol", "simulator"):
        raise SensorlessError(f"--acceleration must be savgol or simulator, got '{acceleration}'")
    with atomic_outdir(out, force) as tmp:
        res = run(tmp, quick=quick, seed=seed, console=console, acceleration=acceleration,
                  coulomb_smoothing=coulomb_smoothing)
    console.print((out / "table.md").read_text())
    console.print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res["checks"].items()})
    console.print(f"wrote {out}/")

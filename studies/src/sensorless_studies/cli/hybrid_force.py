"""`sensorless experiment hybrid-force` (:mod:`sensorless_studies.experiments.hybrid_force`)."""

from __future__ import annotations

from pathlib import Path

from sensorless.cli.common import atomic_outdir, guarded
from sensorless.cli.console import console

from .common import experiment_app, experiment_options

__all__ = ["experiment_hybrid_force"]


@experiment_app.command("hybrid-force")
@guarded
@experiment_options("sensorless-results/hybrid_force", quick="shorter logs and training (≈1 min on 2 cores)",
                    seed="random seed (simulation, training, bootstrap)")
def experiment_hybrid_force(out: Path, quick: bool, seed: int, force: bool) -> None:
    """Model-based vs hybrid vs learning-only force estimation for a simulated PSM-like arm in a trocar
    (Tables II–IV) + payload identification; writes results.json, tables.md and figures."""
    from ..experiments.hybrid_force import run

    with atomic_outdir(out, force) as tmp:
        run(tmp, quick=quick, seed=seed, console=console)
    console.print(f"wrote {out}/")

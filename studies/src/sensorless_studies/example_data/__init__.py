"""Data for the documented commands: ``sensorless example NAME --out DIR`` writes exactly the logs,
models and gain files one quickstart or doc uses, simulated (seeded) so it runs anywhere.

One module per example; each exposes ``write(out: Path, *, full: bool, seed: int) -> list[str]``
(the file names it wrote, relative to ``out``) and a one-line docstring. :data:`EXAMPLES` is the
registry: one line per example. ``full=False`` (the default) is seconds; ``full=True`` the
documented size. This package is an application layer (it imports ``sensorless_studies.simulation``).
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Callable

__all__ = ["EXAMPLES", "example_names", "example_summary", "write_example"]

#: name → module (under this package) that writes it
EXAMPLES: dict[str, str] = {
    "arm": "arm",
    "current-arm": "current_arm",
    "drive-bench": "drive_bench",
    "drive-gains": "drive_gains",
    "dvrk-psm": "dvrk_psm",
    "fleet-logs": "fleet_logs",
    "friction-bench": "friction_bench",
    "held-arm": "held_arm",
    "paired-runs": "paired_runs",
    "pushed-arm": "pushed_arm",
    "rail-leg": "rail_leg",
    "ros2-bag": "ros2_bag",
    "solo12-walk": "solo12_walk",
    "talos-leg-drive": "talos_leg_drive",
    "talos-walk": "talos_walk",
    "trocar-arm": "trocar_arm",
}


def example_names() -> list[str]:
    return sorted(EXAMPLES)


def _module(name: str):
    return importlib.import_module(f"{__name__}.{EXAMPLES[name]}")


def example_summary(name: str) -> str:
    """The first line of the example module's docstring."""
    return (_module(name).__doc__ or "").strip().splitlines()[0]


def write_example(name: str, out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    """Write example ``name`` into the existing directory ``out``; the files written."""
    write: Callable = _module(name).write
    return list(write(Path(out), full=full, seed=seed))

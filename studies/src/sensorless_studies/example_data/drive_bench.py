"""Bench logs of a drive: motor current and output torque, load-dependent Coulomb friction (docs/friction.md)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from ..simulation.drive_bench import DriveBench, simulate_drive_bench, write_drive_csv

    bench = DriveBench(load=0.15)
    duration = 30.0 if full else 10.0
    names = [f"drive_{c}.csv" for c in "abc"]
    for i, name in enumerate(names):
        write_drive_csv(simulate_drive_bench(bench, duration=duration, seed=seed + i), out / name)
    return names

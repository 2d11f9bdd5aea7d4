"""Parquet logs of a simulated Panda (7 arm joints) in two sub-folders (docs/fleet.md, README quickstart 6)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from sensorless.robot import load_robot
    from ..simulation.fleet_logs import write_fleet_logs

    robot = load_robot("panda", lock_joints=("panda_finger_joint1", "panda_finger_joint2"))
    # --full: the smaller size of `sensorless benchmark dask` (10 files of 10⁵ samples at 1 kHz)
    n, size, rate, freq = (10, 100_000, 1000.0, 0.05) if full else (4, 3000, 500.0, 0.1)
    paths = write_fleet_logs(robot, out, n, size, rate=rate, base_freq=freq, seed=seed, subdirs=2)
    return [str(p.relative_to(out)) for p in paths]

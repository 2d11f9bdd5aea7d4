"""Speed of the quadruped simulation: wall time per simulated second (``simulate``, Solo12)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

from sensorless.robot import load_robot
from ..simulation.quadruped import simulate

__all__ = ["benchmark_simulation"]


def benchmark_simulation(
    duration: float = 10.0, scenarios: Sequence[str] = ("wobble", "trot", "crawl", "jump"), seed: int = 0
) -> dict[str, Any]:
    """Wall time per simulated second for each scenario (Solo12, defaults). JSON-able."""
    out: dict[str, Any] = {"duration": duration, "scenarios": {}}
    robot = load_robot("solo12")
    for name in scenarios:
        t0 = time.perf_counter()
        _, gt = simulate(name, robot, duration=duration, seed=seed)
        wall = time.perf_counter() - t0
        out["scenarios"][name] = {
            "wall_s": wall,
            "wall_per_sim_s": wall / max(gt.settings["duration"], 1e-9),
            "fell": gt.fell,
            "samples": len(gt),
        }
    return out

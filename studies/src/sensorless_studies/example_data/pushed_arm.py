"""A UR5 log for identification and a log pushed twice at tool0 (monitor, README quickstart 5)."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write", "write_pushes"]


def write_pushes(truth, path: Path) -> None:
    """The pushes of a simulated log as JSON: start/end [s after the first sample], peak force [N], frame."""
    pushes = [{"start_s": round(p.start, 3), "end_s": round(p.end, 3), "peak_force": [round(f, 2) for f in p.peak],
               "frame": p.frame} for p in truth.pushes]
    path.write_text(json.dumps({"pushes": pushes}) + "\n")


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from sensorless.data import write_npz
    from ..simulation.arm_push import pushed_arm_scenario

    train, log, truth = pushed_arm_scenario(seed, train_duration=60.0 if full else 20.0)
    write_npz(train, out / "train.npz")
    write_npz(log, out / "pushed.npz")
    write_pushes(truth, out / "pushes.json")
    return ["train.npz", "pushed.npz", "pushes.json"]

"""UR5 logs of motor currents (jittery 100 Hz, idle ends): train.csv, test.csv, gains.json, for docs/arm.md §6."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    """Two runs of different Fourier excitations of one perturbed "true" UR5
    (:func:`sensorless_studies.simulation.current_arm.simulate`: columns ``time, pos_J, vel_J, i_J``,
    i = τ/K + noise, 2 s idle, the motion, 3 s idle) and the drive gains K (joint → N·m/A).
    The size is the same with ``full``: the docs' figures are measured on it."""
    from ..simulation.current_arm import drive_gains_for, simulate, truth_model

    robot, truth = truth_model("ur5", seed)
    gains = drive_gains_for(robot)
    for name, s in (("train", seed + 1), ("test", seed + 2)):
        simulate(robot, truth, gains, seed=s).to_csv(out / f"{name}.csv", index=False)
    (out / "gains.json").write_text(json.dumps(dict(zip(robot.joint_names, map(float, gains))), indent=1))
    return ["train.csv", "test.csv", "gains.json"]

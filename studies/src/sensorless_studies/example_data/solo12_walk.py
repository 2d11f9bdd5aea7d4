"""Three Solo12 walking logs (trot, crawl, trot) with contact flags and IMU, for README quickstart 2 and docs/legged-robot.md."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]

#: file → (scenario, settings); walk3 is the held-out log
LOGS = {"walk1.npz": ("trot", {"speed": 0.2}), "walk2.npz": ("crawl", {}), "walk3.npz": ("trot", {"speed": 0.3})}


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from sensorless.data import write_npz
    from ..simulation.quadruped import simulate

    duration = 30.0 if full else 5.0
    for k, (name, (scenario, settings)) in enumerate(LOGS.items()):
        traj, _ = simulate(scenario, "solo12", duration=duration, seed=seed + k, **settings)
        extras = {key: traj.extras[key] for key in ("contact", "imu_acc")}  # what a robot logs (no foot heights)
        write_npz(traj.with_(extras=extras), out / name)
    return list(LOGS)

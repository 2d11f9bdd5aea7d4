"""A UR5 with stiction: a training log and a log held still and pushed by hand (docs/monitoring.md)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from sensorless.data import write_npz
    from ..simulation.held_arm import held_arm_scenario
    from .pushed_arm import write_pushes

    # --full: the scenario of `sensorless benchmark held-monitor` (60 s, 5 pushes, 30 s training)
    kw = {} if full else dict(duration=30.0, n_pushes=2, train_duration=20.0)
    case = held_arm_scenario(seed, **kw)
    write_npz(case.train, out / "held_train.npz")
    write_npz(case.log, out / "held.npz")
    write_pushes(case.truth, out / "pushes.json")
    return ["held_train.npz", "held.npz", "pushes.json"]

"""Two bench logs of one joint with LuGre friction (train, test), for docs/friction.md."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from ..simulation.lugre import simulate_lugre_joint, write_bench_csv

    duration = 60.0 if full else 20.0
    names = []
    for name, s in (("bench_train.csv", seed), ("bench_test.csv", seed + 1)):
        write_bench_csv(simulate_lugre_joint(duration=duration, seed=s)[0], out / name)
        names.append(name)
    return names

"""Bench logs of one joint with LuGre friction: train, test, and a uniformly sampled pushed log (docs/friction.md)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]

#: the external torque of bench_pushed.csv: (start, end) [s], level [N·m] (the motor torque drops by it)
PUSH = (12.0, 14.0, 0.3)


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from ..simulation.lugre import simulate_lugre_joint, write_bench_csv

    duration = 60.0 if full else 20.0
    names = []
    for name, s in (("bench_train.csv", seed), ("bench_test.csv", seed + 1)):
        write_bench_csv(simulate_lugre_joint(duration=duration, seed=s)[0], out / name)
        names.append(name)
    # the velocity profile is imposed (a stiff velocity loop), so an external torque shows one-to-one in τ
    log, _ = simulate_lugre_joint(duration=20.0, seed=seed + 2, jitter=0.0)
    start, end, level = PUSH
    tau = log.tau.copy()
    tau[(log.t > start) & (log.t < end)] -= level
    write_bench_csv(log.with_(tau=tau), out / "bench_pushed.csv")
    return [*names, "bench_pushed.csv"]

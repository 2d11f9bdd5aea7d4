"""A hopping leg on a passive vertical rail: its CAD URDF (leg.urdf) and two 1 kHz logs with a force plate (hop1.npz, hop2.npz)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from ..simulation.hopping_leg import CAD, TRUTH, leg_urdf, simulate_hops, write_hop_log

    duration = 20.0 if full else 6.0  # 6 s: seconds to simulate, and the logs docs/legged-robot.md's figures are from
    leg_urdf(CAD, out / "leg.urdf")  # the CAD description (the prior); the simulated robot is TRUTH
    for k, name in enumerate(("hop1.npz", "hop2.npz")):  # two logs, different hop patterns
        write_hop_log(simulate_hops(TRUTH, seed=seed + k, duration=duration), out / name)
    return ["leg.urdf", "hop1.npz", "hop2.npz"]

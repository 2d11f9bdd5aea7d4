"""`sensorless benchmark observer | held-monitor | stream`: the momentum observer's step, the monitor on a
held arm with stiction, and `sensorless stream` over UDP (JSON output)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer


from sensorless.cli.console import console
from sensorless.errors import OptionError

from .common import bench_command

__all__ = ["bench_observer", "bench_held_monitor", "bench_stream"]


@bench_command("observer")
def bench_observer(
    samples: int = typer.Option(100_000, help="compiled steps per robot (timed one by one)"),
    python_samples: int = typer.Option(2000, help="Python steps per robot, for comparison"),
    rounds: int = typer.Option(100, help="rounds interleaving the compiled step and the bare C++ loop"),
    robot: List[str] = typer.Option(["ur5", "solo12", "dvrk_psm"], help="robots (repeat the option)"),
) -> dict:
    """Per-sample cost of the momentum observer's step, compiled (C++ kernel) and in Python, against the
    bare C++ computation of M, Cᵀv and g over the same states (UR5, Solo12, dVRK PSM; JSON)."""
    from ..benchmarks.observer import ROBOTS, run

    bad = [r for r in robot if r not in ROBOTS]
    if bad:
        raise OptionError(f"--robot {' '.join(bad)}: not a benchmark robot; choose from {', '.join(ROBOTS)}")
    res = run(samples, python_samples, rounds, robots=robot)
    if res["kernel"] is None:
        console.print(f"compiled step not measured: {res['kernel_reason']}")
    for name, v in res["robots"].items():
        py = v["python_step"]
        line = f"{name} (n = {v['n']}): Python step p50 {py['p50_us']:.1f} µs"
        if v.get("compiled"):
            s, b = v["step"], v["bare_cpp"]
            line += (f"; compiled step mean {s['mean_us']:.2f} µs, p50 {s['p50_us']:.2f}, p99 {s['p99_us']:.2f}, "
                     f"p99.9 {s['p999_us']:.1f}, max {s['max_us']:.0f} µs, {s['over_1ms']} over 1 ms; bare C++ "
                     f"M, Cᵀv, g mean {b['mean_us']:.2f} µs; ratio {v['ratio']:.2f} (p50s {v['ratio_p50']:.2f})")
        elif v.get("reason"):
            line += f"; Python only: {v['reason']}"
        console.print(line)
    console.print(f"load average {res['load_average_before'][0]:.2f} before, {res['load_average_after'][0]:.2f} after")
    return res


@bench_command("held-monitor", "held_monitor")
def bench_held_monitor(
    seeds: int = typer.Option(10, help="simulated held-still arms (seeds first_seed, first_seed + 1, …)"),
    first_seed: int = typer.Option(0, help="first seed"),
) -> dict:
    """A UR5 with stiction held still and pushed 5 times per seed: pushes found, false alarms per
    minute, force at rest vs the noise-implied force, for --order 1, 2 and without the dead zone."""
    from ..benchmarks.held_monitor import run

    res = run(seeds, first_seed)
    for name in ("order1", "order2", "no_dead_zone"):
        s = res[name]
        console.print(f"{name}: all pushes found {s['all_pushes_found']}, max false alarms {s['max_false_alarms_per_minute']:.2f}"
                      f"/min, max rest force / noise-implied {s['max_rest_force_ratio']:.2f}, "
                      f"mean contact fraction {s['mean_contact_fraction']:.3f}")
    return res


@bench_command("stream")
def bench_stream(
    samples: int = typer.Option(100_000, help="samples sent (at --rate: 10⁵ at 1 kHz is 100 s)"),
    rate: float = typer.Option(1000.0, help="send rate [Hz]; also the simulated log's sample rate"),
    format: str = typer.Option("binary", "--format", help="record encoding: binary or csv"),
    frame: Optional[str] = typer.Option("tool0", help="force frame of the UR5 ('' for none)"),
    work: Optional[Path] = typer.Option(None, help="folder for the simulated logs, model and thresholds (default: a "
                                        "temporary folder, deleted)"),
) -> dict:
    """A UR5 `sensorless stream` subprocess fed over UDP on the loopback at --rate from a simulated pushed
    log (model from `sensorless identify`, thresholds from `sensorless monitor`): dropped samples, latency
    send → estimate received (p50/p99/p99.9/max) and the stream's CPU time."""
    from ..benchmarks.stream import bench_stream as run

    if samples < 1 or not rate > 0:
        raise OptionError("--samples must be ≥ 1 and --rate > 0")
    if format not in ("csv", "binary"):
        raise OptionError(f"--format {format}: choose csv or binary")
    return run(samples, rate, format, frame or None, work, console=console)

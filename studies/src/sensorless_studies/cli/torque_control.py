"""Torque control of a position-controlled leg: the study and the actuator-fit benchmark."""

from __future__ import annotations

from pathlib import Path

import typer

from sensorless.cli.common import atomic_outdir, guarded
from sensorless.cli.console import console

from .common import bench_command, experiment_app, experiment_options


@experiment_app.command("torque-control")
@guarded
@experiment_options("sensorless-results/torque_control", quick="shorter protocols (≈ 30 s on 2 cores)",
                    seed="random seed (sensor noise, model error, protocols)")
def experiment_torque_control(out: Path, quick: bool, seed: int, force: bool) -> None:
    """Simulated TALOS leg, position-controlled drives: F/T + IMU torque estimation, actuator fits
    (a), swing tracking position vs torque control at K6 = 1 … 0.1 (b), force tracking (c),
    open loop with symmetric vs asymmetric motor model (d); writes results.json and figures."""
    from ..experiments.torque_control import run

    with atomic_outdir(out, force) as tmp:
        res = run(tmp, quick=quick, seed=seed, console=console)
    acc = res["acceptance"]
    console.print(
        f"K6 = 1 torque control beats position control (mean and max, every joint): "
        f"{acc['k6_1_torque_beats_position_mean_and_max_every_joint']}; asymmetric fit over-estimates at most "
        f"{100 * acc['asymmetric_over_estimation_max']:.1f} % of samples; open loop, joints running away: "
        f"{acc['open_loop_joints_running_away']}"
    )
    console.print(f"wrote {out}/")


@bench_command("actuator-fit", "actuator_fit")
def bench_actuator_fit(
    samples: int = typer.Option(10_000_000, help="number of samples of one joint"),
    weight: float = typer.Option(100.0, help="asymmetric weight w"),
    repeats: int = typer.Option(3, help="timed fits (the first one includes buffer allocation)"),
    seed: int = typer.Option(0, help="random seed of the synthetic data"),
) -> dict:
    """Asymmetric-penalty actuator fit (Newton, exact optimality on the active set): wall time on N samples."""
    from ..benchmarks.actuator import benchmark_asymmetric_fit
    from sensorless.errors import DataError

    if samples < 10:
        raise DataError(f"--samples must be ≥ 10, got {samples}")
    res = benchmark_asymmetric_fit(samples, weight=weight, seed=seed, repeats=repeats)
    console.print(
        f"{samples:,} samples: first fit {res['seconds_first']:.2f} s, best {res['seconds_best']:.2f} s, "
        f"{res['iterations']} Newton iterations, over-estimated {100 * res['over_estimation_fraction']:.1f} % "
        f"(target < {res['target_seconds']:.0f} s: {'met' if res['meets_target'] else 'NOT met'})"
    )
    return res

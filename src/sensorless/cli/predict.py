"""`sensorless predict` (torques of a log from an identified model) and `sensorless demo`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from ..errors import SensorlessError
from ..io import write_npz_atomic
from .common import (
    ROBOT_HELP,
    app,
    atomic_outdir,
    check_preprocessing,
    console,
    gains_option,
    guarded,
    load_logs,
    load_robot_arg,
    max_gap_option,
    model_preprocessing,
    output_file,
    path_inputs,
    resample_option,
    trim_option,
    velocity_option,
)


@app.command()
@guarded
def predict(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    model: Path = typer.Option(..., help="result.json (or its directory) from `sensorless identify`"),
    data: Path = typer.Option(..., help="log to predict"),
    out: Path = typer.Option(..., help="output .npz with t, tau_pred (and tau_measured, metrics if available)"),
    columns: Optional[str] = typer.Option(None, help="column map (default: the model's)"),
    rate: Optional[float] = typer.Option(None, help="sample rate (Hz) for logs without a time column (default: the model's)"),
    savgol_window: Optional[int] = typer.Option(None, help="Savitzky-Golay window (default: the model's)"),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off in Hz (default: the model's)"),
    gains: Optional[str] = gains_option(),
    trim: Optional[str] = trim_option(),
    resample: Optional[str] = resample_option(None),
    velocity: Optional[str] = velocity_option(None),
    max_gap: Optional[float] = max_gap_option(),
    lock: Optional[List[str]] = typer.Option(None),
    floating_base: Optional[bool] = typer.Option(None, "--floating-base/--fixed-base"),
    outliers: str = typer.Option("error", help="gross outliers in the log: error | drop | keep"),
) -> None:
    """Predict joint torques of a log with an identified model. The log is preprocessed as the
    model's training logs were (result.json settings.preprocessing) unless an option says otherwise."""
    from ..estimators import load_parameters
    from ..identification.metrics import torque_metrics
    from ..report import metrics_table

    check_preprocessing(rate, lowpass, savgol_window, 1)
    output_file(out, path_inputs(robot, model, data))
    r = load_robot_arg(robot, lock, floating_base)
    path = model / "result.json" if model.is_dir() else model
    structure, params = load_parameters(path, r)
    opts = model_preprocessing(path, columns=columns, gains=gains, rate=rate, resample=resample, lowpass=lowpass,
                               savgol_window=savgol_window, velocity=velocity, max_gap=max_gap)
    (traj,) = load_logs([data], r, opts["columns"], opts["rate"], opts["lowpass"], opts["savgol_window"], 1,
                        gains=opts["gains"], trim=trim, resample=opts["resample"], velocity=opts["velocity"],
                        max_gap=opts["max_gap"], outliers=outliers, rest=opts.get("rest"))
    pred = structure.torques(params, traj)
    if not np.all(np.isfinite(pred)):
        raise SensorlessError(f"{path}: the model predicts non-finite torques on {data}")
    arrays = {"t": traj.t, "tau_pred": pred, "joints": np.array(structure.row_names),
              "preprocessing": np.array(json.dumps({**opts, "trim": trim, "signals": traj.provenance}))}
    if traj.tau is not None:
        meas = structure.target(traj)
        arrays["tau_measured"] = meas
        console.print(metrics_table(Path(data).name, {"model": torque_metrics(meas, pred, structure.row_names)}))
    write_npz_atomic(out, **arrays)
    console.print(f"wrote {out}")


@app.command()
@guarded
def demo(
    out: Path = typer.Option(Path("demo_output"), help="output directory"),
    seed: int = typer.Option(0, help="random seed"),
) -> None:
    """End-to-end example on a simulated Panda: excite, identify, validate, export."""
    from ..demo import run_demo

    with atomic_outdir(out, force=True) as tmp:
        run_demo(tmp, seed=seed, console=console)
    console.print(f"wrote {out}/")

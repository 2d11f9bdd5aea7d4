"""`sensorless predict`: torques of a log from an identified model (`sensorless demo` is in sensorless-studies)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import OptionError, SensorlessError
from .options import Outliers
from .common import (app, floating_base_option, force_option, guarded, lock_option, model_logs, output_file, path_inputs,
                     printed_warnings)
from .console import console
from .applied_model import MODEL_HELP, applied_model_options, passive_option, robot_and_model


@app.command()
@guarded
@applied_model_options(MODEL_HELP + " or `sensorless friction`", robot_required=False)
def predict(
    robot: Optional[str],
    model: Optional[Path],
    data: Path = typer.Option(..., help="log to predict"),
    out: Path = typer.Option(..., help="output .npz with t, tau_pred, joints, model (and tau_measured, metrics (JSON) if "
                                       "available)"),
    lock: Optional[List[str]] = lock_option("joints to lock (default: the model's, settings.robot)"),
    passive: Optional[List[str]] = passive_option(),
    floating_base: Optional[bool] = floating_base_option(),
    outliers: Outliers = typer.Option(Outliers.error, help="gross outliers in the log"),
    force: bool = force_option(),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write OUT.png (measured and predicted effort with the "
                                                            "residual, per joint) and OUT.html (metrics and figure)"),
    prep: dict = None,
) -> None:
    """Predict joint torques of a log with an identified model, loaded on the robot as it was identified
    (locks, passive joints, floating base, contact frames: from the model). The log is preprocessed as the
    model's training logs were (result.json settings.preprocessing) unless an option says otherwise.
    Without --model (or with --model ROBOT.urdf) the robot description's own parameters are the model
    (the prior, labelled so). A friction-only model (`sensorless friction`) needs no --robot; its
    friction states are integrated along the log from zero. Beside OUT (unless --no-plot): OUT.png, measured
    against predicted with the residual per joint, and OUT.html, the metrics (joints at rest: RMSE and bias)
    and the figure on one page."""
    import numpy as np

    from ..data.prepare import check_preprocessing
    from ..identification.artifact import is_friction_model
    from ..identification.metrics import static_rows, torque_metrics
    from ..io import write_npz_atomic
    from ..report import metrics_table

    check_preprocessing(prep["rate"], prep["lowpass"], prep["savgol_window"], 1)
    output_file(out, path_inputs(robot, model, data), force)
    png, html = Path(out).with_suffix(".png"), Path(out).with_suffix(".html")
    if plot and Path(out).suffix.lower() in (".png", ".html"):
        raise OptionError(f"--out {out}: the predictions go to an .npz file (the figure and page are written beside it)")
    if plot:
        output_file(png, path_inputs(robot, model, data), force)
        output_file(html, path_inputs(robot, model, data), force)
    if model is not None and is_friction_model(model):
        from .friction import predict_friction

        return predict_friction(model, data, out, prep)
    if robot is None:
        raise OptionError("--robot is required unless --model is a friction-only model from `sensorless friction`")
    r, art = robot_and_model(robot, model, lock=lock, passive=passive, floating=floating_base)
    path, structure, params = art.path, art.structure, art.parameters
    console.print(f"model: {art.label}", highlight=False, soft_wrap=True)
    (traj,), opts = model_logs(art, [data], r, prep, outliers=outliers)
    trim = prep["trim"]
    pred = structure.torques(params, traj)
    if not np.all(np.isfinite(pred)):
        raise SensorlessError(f"{path}: the model predicts non-finite torques on {data}")
    arrays = {"t": traj.t, "tau_pred": pred, "joints": np.array(structure.row_names),
              "model": np.array(art.origin), "model_label": np.array(art.label),
              "preprocessing": np.array(json.dumps({**opts, "trim": trim, "signals": traj.provenance}))}
    metrics = meas = None
    if traj.tau is not None:
        meas = structure.target(traj)
        arrays["tau_measured"] = meas
        name = "prior" if art.origin == "prior" else "model"
        rows = structure.row_names  # a joint held still in the log: RMSE and bias, not NRMSE (as identify --validate)
        metrics = torque_metrics(meas, pred, rows, static=static_rows(traj, rows))
        arrays["metrics"] = np.array(json.dumps(metrics.to_dict()))
        console.print(metrics_table(Path(data).name, {name: metrics}))
    write_npz_atomic(out, **arrays)
    if plot:
        from ..report.predict_report import write_predict_report

        write_predict_report(png if meas is not None else None, html, t=traj.t, measured=meas, predicted=pred,
                             rows=list(structure.row_names), robot=structure.robot,
                             metrics=None if metrics is None else metrics.to_dict(), model_label=art.label,
                             log=str(data), notes=printed_warnings())
    console.print(f"wrote {out}" + (f", {png}, {html}" if plot and meas is not None else f", {html}" if plot else ""))

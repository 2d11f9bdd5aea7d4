"""`sensorless payload`: mass, CoM and inertia of a load carried by a known link or frame."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import ExcitationError, SensorlessError
from .frames import frame_options
from .common import (
    robot_source_options,
    log_reading_options,
    model_logs,
    model_preprocessing_options,
    MultiValueCommand,
    app,
    guarded,
    force_option,
    lock_option,
    model_options,
    output_file,
    path_inputs,
)
from ..run.logs import log_settings
from .console import console, safe
from .logs import print_pairing
from .options import ALIGN_HELP, Align, PayloadMode
from .progress import progress_bars

__all__ = ["payload"]


def parse_vector(text: Optional[str], what: str) -> Optional[np.ndarray]:
    """A 3-vector from ``"x,y,z"`` (None for None); ``what`` names the option in the error."""
    import numpy as np
    if text is None:
        return None
    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        raise SensorlessError(f"{what} must be three comma-separated numbers, got '{text}'") from None
    if v.shape != (3,):
        raise SensorlessError(f"{what} must be three comma-separated numbers, got '{text}'")
    return v


@app.command(cls=MultiValueCommand)
@guarded
@robot_source_options
@frame_options
@model_preprocessing_options(("columns", "rate", "lowpass", "savgol_window", "gains", "trim", "resample"))
@model_options("result.json (or its directory) of the robot identified WITHOUT the payload")
@log_reading_options()
def payload(
    robot: str,
    model: Path,
    data: List[Path] = typer.Option(..., help="log(s) recorded with the payload attached"),
    frame: str = typer.Option(..., help="link (joint frame) or frame carrying the payload, e.g. tool_tip"),
    out: Path = typer.Option(..., help="output JSON (written atomically)"),
    no_load: List[Path] = typer.Option([], help="paired log(s) without the payload: the same trajectory, one per "
                                               "--data; cancels what the model misses"),
    align: Align = typer.Option(Align.auto, help=ALIGN_HELP.replace("the two runs", "--no-load with --data")),
    offsets: str = typer.Option("auto", help="constant torque offset per joint (session drift, recalibration): auto "
                                             "(where distinguishable from the payload) | all | none | JOINT,JOINT"),
    mode: PayloadMode = typer.Option(PayloadMode.auto, help="auto | full (10 inertial parameters) | com (point mass: m, CoM) | mass (CoM given)"),
    com: Optional[str] = typer.Option(None, help="payload CoM 'x,y,z' [m] in the frame: mode mass (default the frame "
                                               "origin), and m from m·c at a frame whose origin the log does not move"),
    accept_implausible: bool = typer.Option(False, help="write a payload mass that is not finite or heavier than the "
                                            "whole robot model (refused by default)"),
    accept_bound: bool = typer.Option(False, help="write a result whose mass sits at its bound 0 (labelled 'at bound: "
                                                  "not determined') instead of refusing it"),
    n_boot: int = typer.Option(200, help="block-bootstrap resamples (0: HAC covariance only)"),
    block_seconds: float = typer.Option(1.0, help="block length [s] of the HAC covariance and the bootstrap"),
    flag_sigma: float = typer.Option(3.0, help="flag a joint whose own mass is this many σ from the estimate ..."),
    flag_rel: float = typer.Option(0.1, help="... and differs from it by more than this fraction"),
    lock: Optional[List[str]] = lock_option(),
    seed: int = typer.Option(0, help="bootstrap seed"),
    force: bool = force_option(),
    prep: dict = None,
) -> None:
    """Identify a payload at FRAME from the torque the robot's model does not explain:
    τ − Wπ̂ = Gᵀ J_fᵀ Φ_f φ (+ per-joint offsets), paired with a no-load log when given.
    Reports mass (and m·g), CoM, uncertainty (HAC / block bootstrap) and per-joint consistency."""
    import numpy as np
    from ..identification.payload import identify_payload
    from .applied_model import robot_and_model
    from ..io import write_json_atomic

    output_file(out, path_inputs(robot, model, data, no_load), force)
    if no_load and len(no_load) != len(data):
        raise SensorlessError(f"{len(data)} --data log(s) but {len(no_load)} --no-load log(s); pair them one to one")
    r, art = robot_and_model(robot, model, lock=lock)  # the robot as identified (settings.robot)
    path, structure, params = art.path, art.structure, art.parameters
    every, opts = model_logs(art, [*data, *no_load], r, prep)
    logs, refs = every[:len(data)], (every[len(data):] or None)
    read = list(every)
    pairings = []
    if refs is not None:
        from ..data.align import pair_logs

        pairs = [pair_logs(a, b, str(align)) for a, b in zip(logs, refs)]
        logs, refs, pairings = (list(x) for x in zip(*pairs))
        for p in pairings:
            print_pairing(p.to_dict())
    off = {"auto": "auto", "all": True, "none": False}.get(offsets.strip().lower(),
                                                           [j.strip() for j in offsets.split(",") if j.strip()])
    with progress_bars() as bars:
        est = identify_payload((structure, params), logs, frame, no_load=refs, offsets=off, mode=mode,
                               com=parse_vector(com, "--com"), n_boot=n_boot, block_seconds=block_seconds,
                               flag_sigma=flag_sigma, flag_rel=flag_rel, seed=seed,
                               progress=bars.callback("payload block bootstrap (resamples)"))
    if est.mass_at_bound and not accept_bound:
        raise ExcitationError(
            f"payload at '{frame}': the mass is at its bound 0 (least squares without the bound: "
            f"{est.diagnostics['mass_unconstrained']:.4g} kg), so the log does not determine it; no payload is visible "
            "at this frame, or the model or frame is wrong; rerun with --accept-bound to write it labelled 'at bound'")
    _check_payload_mass(est, r, frame, accept_implausible)
    doc = {"robot": r.name, "model": str(path), "data": [str(p) for p in data], "no_load": [str(p) for p in no_load],
           "alignment": [p.to_dict() for p in pairings], **est.to_dict()}
    gain_std = _gain_std(opts["gains"], r)
    if gain_std is not None:  # identified gains (sensorless drive-gains): their uncertainty enters the mass
        dm = []
        for k, rel in enumerate(gain_std):
            scale = np.ones(r.n_actuated)
            scale[k] += rel
            sl = [_scaled(t, r, scale) for t in logs]
            sr = [_scaled(t, r, scale) for t in refs] if refs is not None else None
            e = identify_payload((structure, params), sl, frame, no_load=sr, offsets=off, mode=est.mode,
                                 com=parse_vector(com, "--com"), n_boot=0, block_seconds=block_seconds, seed=seed)
            dm.append(e.mass - est.mass)
        std_g = float(np.sqrt(np.sum(np.square(dm))))
        doc.update({"mass_std_noise": est.mass_std, "mass_std_gains": std_g,
                    "mass_std": float(np.hypot(est.mass_std, std_g)),
                    "mass_sensitivity_to_gains": dict(zip(r.actuated_joints, map(float, dm)))})
        est.mass_std = doc["mass_std"]
    doc.setdefault("settings", {})["preprocessing"] = {**opts, **log_settings(prep["trim"], [*data, *no_load], read)}
    doc["settings"]["align"] = str(align)
    write_json_atomic(doc, out)
    _print(est)
    console.print(f"wrote {out}")


def _check_payload_mass(est, robot, frame: str, accept: bool) -> None:
    """PlausibilityError for a payload mass that is not finite or heavier than the whole robot model
    (no model states a payload rating; a robot that carries more than itself is a unit or model error)."""
    import numpy as np
    from ..errors import PlausibilityError

    total = float(sum(robot.model.inertias[j].mass for j in range(1, robot.model.njoints)))
    m = float(est.mass)
    if accept:
        return
    if not np.isfinite(m):
        raise PlausibilityError(f"payload at '{frame}': the mass is {m}; check the logs and --frame "
                                "(--accept-implausible writes it anyway)")
    if total > 0 and m > total:
        raise PlausibilityError(f"payload at '{frame}': mass {m:.4g} kg is more than the whole robot model "
                                f"({total:.4g} kg); check the units, --gains and --frame (--accept-implausible writes "
                                "it anyway)")


def _gain_std(gains, robot):
    """Relative std per actuated joint of gains from a `sensorless drive-gains` file, else None."""
    import numpy as np
    from ..io import read_json

    if not isinstance(gains, (str, Path)) or not str(gains).lower().endswith(".json") or not Path(gains).is_file():
        return None
    try:
        doc = read_json(gains, "gains file")
        g, s = doc["gains"], doc["std"]
        return np.array([float(s[j]) / float(g[j]) if j not in doc.get("from_nominal", []) else 0.0
                         for j in robot.actuated_joints])
    except (ValueError, KeyError, TypeError, ZeroDivisionError):
        return None


def _scaled(traj, robot, scale):
    """``traj`` with the torque of actuated joint k scaled by ``scale[k]`` (a gain perturbed)."""
    import numpy as np
    names = list(traj.joint_names)
    f = np.ones(len(names))
    for k, j in enumerate(robot.actuated_joints):
        if j in names:
            f[names.index(j)] = scale[k]
    return traj.with_(tau=traj.tau * f)


def _cell(x: float, fmt: str, unit: str = "") -> str:
    """``x`` formatted, or "—" when the joint gives no finite value (no information on the payload)."""
    import math

    return f"{x:{fmt}}{unit}" if isinstance(x, (int, float)) and math.isfinite(x) else "—"


def _print(est) -> None:
    from rich.table import Table

    c, cs = est.com * 1e3, est.com_std * 1e3 if est.com_std is not None else None
    if est.mass > 0:
        com = "(" + ", ".join(f"{x:.1f}" + (f" ± {s:.1f}" if cs is not None else "") for x, s in zip(c, cs if cs is not None else c)) + ") mm"
    else:
        com = f"undefined (least-squares mass without the m ≥ 0 bound: {est.diagnostics['mass_unconstrained']:.4f} kg)"
    det = est.determinacy
    m_txt = ("at its bound 0: not determined" if est.mass_at_bound else
             f"{est.mass:.4f} ± {est.mass_std:.4f} kg (m·g = {est.weight:.3f} ± {est.mass_std * est.gravity:.3f} N)")
    console.print(f"[bold]payload at '{est.frame}'[/] \\[{est.mode}]: m = {m_txt}, CoM = {com}, "
                  f"physically consistent: {est.consistent}")
    console.print("determined by the log: " + ", ".join(f"{k.replace('_', ' ')} {det[k]}" for k in
                                                         ("mass", "first_moment", "inertia") if k in det))
    if est.headline_excludes:
        console.print(f"[yellow]joint(s) {est.headline_excludes} contradict the others and are left out of the "
                      f"estimate[/] (with them: m = {est.diagnostics['mass_with_flagged']:.4f} kg)")
    table = Table(title="per-joint consistency: mass this joint alone implies vs the other joints (CoM fixed)",
                  caption="—: the joint's torque carries no information on the payload mass")
    for col in ("joint", "mass [kg]", "± σ", "others [kg]", "± σ", "z", "share", "offset", "flag"):
        table.add_column(col, justify="right")
    fitted = set(est.settings.get("offsets") or ())
    for k, j in enumerate(est.per_joint):
        flag = "[red]CONTRADICTS[/]" if j.flagged else ("ok" if j.informative else "no info")
        table.add_row(safe(j.joint), _cell(j.mass, ".4f"), _cell(j.std, ".4f"), _cell(j.others_mass, ".4f"),
                      _cell(j.others_std, ".4f"), _cell(j.z, "+.1f"), _cell(100 * j.share, ".0f", " %"),
                      f"{est.offsets[k]:.3g}" if est.offsets is not None and j.joint in fitted else "—", flag)
    console.print(table)

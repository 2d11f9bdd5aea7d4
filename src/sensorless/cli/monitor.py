"""Commands: ``sensorless monitor`` (collision detection with the momentum observer) and
``sensorless benchmark observer`` (per-sample cost of the streaming observer)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from ..errors import SensorlessError
from .frames import frame_options
from .common import (
    robot_source_options,
    log_reading_options,
    model_logs,
    model_preprocessing_options,
    app,
    atomic_outdir,
    bench_command,
    console,
    guarded,
    path_inputs,
    force_option,
    lock_option,
    floating_base_option,
    model_options,
)
from .applied_model import MODEL_HELP, passive_option, robot_and_model
from .options import ForceReference

__all__ = ["monitor", "bench_observer"]


def _parse_quiet(spec: str) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in spec.split(":"))
    except ValueError:
        raise SensorlessError(f"--quiet must be START:END in seconds (e.g. 0:2), got '{spec}'") from None
    if not b > a:
        raise SensorlessError(f"--quiet END must be after START, got '{spec}'")
    return a, b


@app.command()
@guarded
@robot_source_options
@frame_options
@model_preprocessing_options()
@model_options(MODEL_HELP, required=False)
@log_reading_options()
def monitor(
    robot: str,
    model: Optional[Path],
    data: Path = typer.Option(..., help="log to monitor (.csv .npz .parquet .h5)"),
    out: Path = typer.Option(Path("monitor"), help="output directory: monitor.json + monitor.npz (written atomically)"),
    frame: Optional[str] = typer.Option(None, help="frame at which to estimate the Cartesian force (damped J⁻ᵀ)"),
    reference: ForceReference = typer.Option(ForceReference.local_world_aligned, help="frame of the force"),
    quiet: str = typer.Option("0:1", help="START:END [s] of a contact-free segment for the thresholds"),
    k: Optional[float] = typer.Option(None, help="threshold = k σ per joint (default: from --false-alarm-rate)"),
    false_alarm_rate: float = typer.Option(1.0, help="target false alarms per minute (Gaussian model) when --k is not given"),
    gain: float = typer.Option(50.0, help="observer bandwidth K [1/s]"),
    order: int = typer.Option(1, help="observer order: 1 (first-order) or 2 (second-order, filtered)"),
    min_duration: float = typer.Option(0.02, help="shortest reported contact [s]"),
    merge_gap: float = typer.Option(0.05, help="merge contacts separated by less than this [s]"),
    lock: Optional[List[str]] = lock_option("joints to lock (default: the model's, settings.robot)"),
    passive: Optional[List[str]] = passive_option(),
    floating_base: Optional[bool] = floating_base_option(),
    force: bool = force_option(),
    prep: dict = None,
) -> None:
    """Detect contacts/collisions in a log: momentum observer → per-joint thresholds from a
    quiet segment → contact intervals, peak external torque per joint, Cartesian force at --frame.
    The external torque is reported on the actuated and passive joints; for a model identified with
    contacts, it is the part the contacts cannot explain, P(q) r on every row (docs/monitoring.md).
    The robot is loaded as the model was identified; without --model the description's own
    parameters are the model (the prior)."""
    from ..estimation.collision import detect_contacts, quiet_mask, quiet_thresholds
    from ..estimation.momentum import MomentumDynamics, MomentumObserver, _uniform_dt
    from ..estimation.monitored import cartesian_force, monitored_torque

    r, art = robot_and_model(robot, model, lock=lock, passive=passive, floating=floating_base)
    path = art.path
    dyn = MomentumDynamics(art.structure, art.parameters)
    if k is not None and k <= 0:
        raise SensorlessError(f"--k must be > 0, got {k}")
    q0, q1 = _parse_quiet(quiet)
    with atomic_outdir(out, force, inputs=path_inputs(robot, model, data)) as tmp:
        (traj,), opts = model_logs(art, [data], r, prep)
        dt = _uniform_dt(traj)
        res = MomentumObserver(dyn, gain=gain, order=order).run(traj)
        # one convention with estimate-force (docs/monitoring.md): τ_ext = τ_measured − τ_model = Jᵀ F, F the
        # force the robot exerts on its environment at --frame; the observer's r is the torque acting on the robot
        mon = monitored_torque(dyn, res.r, traj)
        tau_ext, names = mon.tau_ext, mon.names
        mask = quiet_mask(traj.t, q0, q1, str(data))
        th = quiet_thresholds(tau_ext, mask, names, k=k, false_alarm_rate=None if k is not None else false_alarm_rate, dt=dt)
        flag, intervals = detect_contacts(tau_ext, traj.t, th, min_duration=min_duration, merge_gap=merge_gap)
        arrays = {"t": traj.t, "tau_ext": tau_ext, "contact": flag, "joints": np.array(names), "r": res.r,
                  "coordinates": np.array(res.names)}
        doc = {
            "data": str(data), "model": str(path), "model_origin": art.origin, "model_label": art.label, "robot": r.name,
            "rows": names, "projected": mon.projector is not None,
            "observer": res.settings, "thresholds": th.to_dict(),
            "quiet_segment_s": [q0, q1],
            "contacts": [iv.to_dict() for iv in intervals],
            "peak_external_torque": {n: float(tau_ext[:, j][np.argmax(np.abs(tau_ext[:, j]))]) for j, n in enumerate(names)},
            "contact_fraction": float(flag.mean()),
        }
        if frame:
            fe = cartesian_force(dyn, traj, mon, frame, reference)
            arrays.update({"force": fe.F, "force_labels": np.array(fe.labels), "sigma_min": fe.sigma_min,
                           "force_unobservable": fe.arrays()["unobservable"]})
            doc["frame"] = {"name": frame, "reference": reference, "labels": fe.labels}
            for iv, d in zip(intervals, doc["contacts"]):
                seg = fe.F[iv.start_index : iv.end_index + 1]
                norm = np.linalg.norm(seg, axis=1)  # NaN on samples with an unobservable component
                if not np.any(np.isfinite(norm)):
                    d.update(peak_force=None, peak_force_norm=None, peak_force_time=None)
                    continue
                i = int(np.nanargmax(norm))
                d["peak_force"] = seg[i].tolist()
                d["peak_force_norm"] = float(norm[i])
                d["peak_force_time"] = float(traj.t[iv.start_index + i])
        from ..io import jsonable

        (tmp / "monitor.json").write_text(json.dumps(jsonable(doc), indent=2, allow_nan=False))
        np.savez(tmp / "monitor.npz", **arrays)
    console.print(f"model: {art.label}" + ("; external torque projected by the contacts, P(q) r" if doc["projected"]
                                           else ""), highlight=False, soft_wrap=True)
    console.print(f"observer order {order}, K = {gain:g} 1/s; thresholds k = {th.k:.2f} σ from {th.samples} quiet samples")
    for iv, d in zip(intervals, doc["contacts"]):
        f = (f", |F| peak {d['peak_force_norm']:.1f} N at {d['peak_force_time']:.2f} s"
             if frame and d.get("peak_force_norm") is not None else ", |F| unobservable at this frame" if frame else "")
        console.print(f"contact {iv.start:8.3f} – {iv.end:8.3f} s  joints {','.join(iv.joints)}{f}")
    console.print(f"{len(intervals)} contact interval(s); wrote {out}/")


@bench_command("observer")
def bench_observer(
    samples: int = typer.Option(2000, help="streaming steps per robot"),
) -> dict:
    """Per-sample cost of MomentumObserver.step (streaming) and .run (offline) on UR5, Solo12, dVRK PSM."""
    from ..estimation.momentum import benchmark_observer

    res = benchmark_observer(samples)
    for name, v in res["robots"].items():
        console.print(f"{name} (n = {v['n']}): step {v['step_us']:.1f} µs/sample, run {v['run_us']:.1f} µs/sample")
    return res

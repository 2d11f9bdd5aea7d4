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
    load_robot_arg,
    path_inputs,
    force_option,
    lock_option,
    floating_base_option,
    model_options,
)
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
@model_options("result.json (or its directory) from `sensorless identify` or `sensorless friction`",
               robot_required=False)
@log_reading_options()
def monitor(
    robot: Optional[str],
    model: Path,
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
    lock: Optional[List[str]] = lock_option(),
    floating_base: Optional[bool] = floating_base_option(),
    force: bool = force_option(),
    prep: dict = None,
) -> None:
    """Detect contacts/collisions in a log: momentum observer → per-joint thresholds from a
    quiet segment → contact intervals, peak external torque per joint, Cartesian force at --frame."""
    from ..estimation.collision import detect_contacts, quiet_mask, quiet_thresholds
    from ..estimation.momentum import MomentumDynamics, MomentumObserver, _uniform_dt
    from ..identification.artifact import load_model_folder

    from ..identification.artifact import is_friction_model

    bench = is_friction_model(model)  # a friction-only model: its joints and friction state, no robot
    if bench and frame:
        raise SensorlessError("--frame needs a robot model; a friction-only model (sensorless friction) has none")
    if not bench and robot is None:
        raise SensorlessError("--robot is required for a model from `sensorless identify`")
    r = None if bench else load_robot_arg(robot, lock, floating_base)
    art = None if bench else load_model_folder(model, r)
    if bench:
        from ..estimation.friction_dynamics import FrictionDynamics
        from .friction import friction_model_log

        bench_art, bench_log, _ = friction_model_log(model, data, prep, need_acceleration=False)
        path, dyn = bench_art.path, FrictionDynamics(bench_art.model)
    else:
        path, dyn = art.path, MomentumDynamics(art.structure, art.parameters)
    if k is not None and k <= 0:
        raise SensorlessError(f"--k must be > 0, got {k}")
    q0, q1 = _parse_quiet(quiet)
    with atomic_outdir(out, force, inputs=path_inputs(robot, model, data)) as tmp:
        (traj,) = (bench_log,) if bench else model_logs(art, [data], r, prep)[0]
        dt = _uniform_dt(traj)
        res = MomentumObserver(dyn, gain=gain, order=order).run(traj)
        # one convention with estimate-force (docs/monitoring.md): τ_ext = τ_measured − τ_model = Jᵀ F, F the
        # force the robot exerts on its environment at --frame; the observer's r is the torque acting on the robot
        tau_ext = -res.tau_ext
        names = dyn.actuated_names
        mask = quiet_mask(traj.t, q0, q1, str(data))
        th = quiet_thresholds(tau_ext, mask, names, k=k, false_alarm_rate=None if k is not None else false_alarm_rate, dt=dt)
        flag, intervals = detect_contacts(tau_ext, traj.t, th, min_duration=min_duration, merge_gap=merge_gap)
        arrays = {"t": traj.t, "tau_ext": tau_ext, "contact": flag, "joints": np.array(names), "r": res.r,
                  "coordinates": np.array(res.names)}
        doc = {
            "data": str(data), "model": str(path), "robot": None if bench else r.name,
            "observer": res.settings, "thresholds": th.to_dict(),
            "quiet_segment_s": [q0, q1],
            "contacts": [iv.to_dict() for iv in intervals],
            "peak_external_torque": {n: float(tau_ext[:, j][np.argmax(np.abs(tau_ext[:, j]))]) for j, n in enumerate(names)},
            "contact_fraction": float(flag.mean()),
        }
        if frame:
            fe = _cartesian_force(dyn, traj, tau_ext, frame, reference)
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
    console.print(f"observer order {order}, K = {gain:g} 1/s; thresholds k = {th.k:.2f} σ from {th.samples} quiet samples")
    for iv, d in zip(intervals, doc["contacts"]):
        f = (f", |F| peak {d['peak_force_norm']:.1f} N at {d['peak_force_time']:.2f} s"
             if frame and d.get("peak_force_norm") is not None else ", |F| unobservable at this frame" if frame else "")
        console.print(f"contact {iv.start:8.3f} – {iv.end:8.3f} s  joints {','.join(iv.joints)}{f}")
    console.print(f"{len(intervals)} contact interval(s); wrote {out}/")


def _cartesian_force(dyn, traj, tau_ext, frame: str, reference: str):
    """F at ``frame`` by the damped least squares of :mod:`sensorless.estimation.force`."""
    from ..estimation.force import CartesianForceEstimator, ForceEstimate, damped_least_squares, frame_jacobians

    if not dyn.transmission:
        est = CartesianForceEstimator(dyn.structure.robot, frame, reference)
        Q = dyn.arrays(traj)[0]
        return est.from_external_torque(Q, tau_ext, traj.t)
    # transmission: τ_θ = Gᵀ Jᵀ F, so the Jacobian in coordinates is J G
    st = dyn.structure
    Qt = st.tree.full_configuration(st.joint_values(dyn.arrays(traj)[0]))
    J = frame_jacobians(st.tree, Qt, frame, reference)[:, :3] @ st.G
    sol = damped_least_squares(J, tau_ext)
    return ForceEstimate(traj.t, sol.F, ["fx", "fy", "fz"], frame, reference, tau_ext, sol.sigma_min, sol.damping,
                         unobservable=sol.unobservable)


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

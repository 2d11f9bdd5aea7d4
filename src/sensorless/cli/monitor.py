"""Command: ``sensorless monitor`` (collision detection with the momentum observer; its benchmarks,
``sensorless benchmark observer`` and ``held-monitor``, are in the studies package)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, List, Optional

import typer

from ..errors import SensorlessError
from .common import (app, atomic_outdir, floating_base_option, force_option, guarded, lock_option, model_logs,
                     path_inputs)
from .console import console, safe
from .applied_model import MODEL_HELP, applied_model_options, passive_option, robot_and_model
from .options import ForceReference

if TYPE_CHECKING:
    import numpy as np

__all__ = ["monitor"]


def _nonnegative(text: str, not_a_number: str, out_of_range: str) -> float:
    """``float(text)`` when finite and ≥ 0; else a SensorlessError with the message given for each case."""
    try:
        x = float(text)
    except ValueError:
        raise SensorlessError(not_a_number) from None
    if not (math.isfinite(x) and x >= 0):
        raise SensorlessError(out_of_range)
    return x


def _parse_static_friction(spec: str, names: list[str]):
    """'model' | 'off' | one value for every joint | 'V1,V2,…' in joint order | 'joint=V,…' [N·m]."""
    import numpy as np
    text = spec.strip()
    if text.lower() in ("model", "off"):
        return text.lower()
    parts = [p.strip() for p in text.replace(";", ",").split(",") if p.strip()]

    def num(v: str, what: str) -> float:
        return _nonnegative(v, f"--static-friction {what}: '{v}' is not a number of N·m",
                            f"--static-friction {what}: must be finite and ≥ 0 N·m, got '{v}'")

    if parts and all("=" in p for p in parts):
        given = {k.strip(): num(v, k.strip()) for k, v in (p.split("=", 1) for p in parts)}
        unknown = [k for k in given if k not in names and k != "*"]
        if unknown:
            raise SensorlessError(f"--static-friction names joint(s) {unknown} that are not monitored ({names})")
        if "*" not in given and set(names) - set(given):
            raise SensorlessError(f"--static-friction has no value for {sorted(set(names) - set(given))}; "
                                  "give every joint or a default '*=VALUE'")
        return np.array([given.get(n, given.get("*")) for n in names], float)
    if len(parts) == 1:
        return np.full(len(names), num(parts[0], "value"))
    if len(parts) == len(names) and not any("=" in p for p in parts):
        return np.array([num(p, n) for p, n in zip(parts, names)])
    raise SensorlessError(f"--static-friction must be 'model', 'off', one value, {len(names)} values in joint order "
                          f"{names} or 'joint=VALUE,…', got '{spec}'")


@app.command()
@guarded
@applied_model_options(MODEL_HELP + " or `sensorless friction`", robot_required=False, frames=True)
def monitor(
    robot: Optional[str],
    model: Optional[Path],
    data: Path = typer.Option(..., help="log to monitor (.csv .npz .parquet .h5)"),
    out: Path = typer.Option(Path("monitor"), help="output directory: monitor.json, monitor.npz, monitor.png (written "
                                                   "atomically)"),
    frame: Optional[str] = typer.Option(None, help="frame at which to estimate the Cartesian force (damped J⁻ᵀ)"),
    reference: ForceReference = typer.Option(ForceReference.local_world_aligned, help="frame of the force"),
    quiet: str = typer.Option("0:1", help="contact-free window for the thresholds, like --trim: START:END in seconds "
                                          "after the first sample (negative: before the last), 'abs:T0:T1' the log's stamps"),
    k: Optional[float] = typer.Option(None, help="threshold = k σ per joint (default: from --false-alarm-rate)"),
    false_alarm_rate: float = typer.Option(1.0, help="target false alarms per minute (Gaussian model) when --k is not given"),
    gain: float = typer.Option(50.0, help="observer bandwidth K [1/s]"),
    order: int = typer.Option(1, help="observer order: 1 (first-order) or 2 (second-order, filtered)"),
    static_friction: str = typer.Option("model", help="half-width f_s [N·m] of the dead zone at rest: 'model' (its "
                                        "Coulomb + Stribeck terms; the quiet window where it has none), 'off', one "
                                        "value, one per joint in order, or 'joint=VALUE,…' ('*=' for the rest)"),
    static_margin: float = typer.Option(0.25, help="the dead zone is ±f_s·(1 + this): breakaway friction varies "
                                        "with dwell time, temperature and pose, and f_s was identified in motion"),
    rest_speed: str = typer.Option("auto", help="a joint is at rest while |v| ≤ this [rad/s]; auto: 5 σ of the "
                                   "log's velocity noise"),
    warmup: Optional[float] = typer.Option(None, help="seconds at the start never flagged (default: until the "
                                           "observer has converged)"),
    min_duration: float = typer.Option(0.02, help="shortest reported contact [s]"),
    merge_gap: float = typer.Option(0.05, help="merge contacts separated by less than this or than the observer's "
                                               "settling time [s]"),
    lock: Optional[List[str]] = lock_option("joints to lock (default: the model's, settings.robot)"),
    passive: Optional[List[str]] = passive_option(),
    floating_base: Optional[bool] = floating_base_option(),
    force: bool = force_option(),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write monitor.png: τ_ext per joint with its threshold "
                              "band and the contact intervals (monitor_<limb>.png per limb for a robot with several)"),
    prep: dict = None,
) -> None:
    """Detect contacts/collisions in a log: momentum observer → per-joint thresholds from a
    quiet window, with the static-friction band as a dead zone on joints at rest → contact
    intervals, peak external torque per joint, Cartesian force at --frame (docs/monitoring.md).
    The external torque is reported on the actuated and passive joints; for a model identified with
    contacts, it is the part the contacts cannot explain, P(q) r on every row. The robot is loaded
    as the model was identified; without --model the description's own parameters are the model
    (the prior)."""
    import numpy as np
    from ..data.trims import TrimWindow
    from ..errors import DataError
    from ..estimation.momentum import MomentumDynamics
    from ..estimation.monitored import MonitoredTorque, cartesian_force, monitored_rows
    from ..estimation.monitoring import MonitorSettings, monitor_log
    from ..estimation.static_band import STATUS
    from ..identification.artifact import is_friction_model

    bench = model is not None and is_friction_model(model)  # a friction-only model: its joints and state, no robot
    if bench and frame:
        raise SensorlessError("--frame needs a robot model; a friction-only model (sensorless friction) has none")
    if not bench and robot is None:
        raise SensorlessError("--robot is required unless --model is a friction-only model from `sensorless friction`")
    if bench:
        from ..estimation.friction_dynamics import FrictionDynamics
        from .friction import friction_model_log

        r = art = None
        bench_art, bench_log, _ = friction_model_log(model, data, prep, need_acceleration=False)
        path, dyn = bench_art.path, FrictionDynamics(bench_art.model)
    else:
        r, art = robot_and_model(robot, model, lock=lock, passive=passive, floating=floating_base)
        path, dyn = art.path, MomentumDynamics(art.structure, art.parameters)
    if k is not None and k <= 0:
        raise SensorlessError(f"--k must be > 0, got {k}")
    if not (np.isfinite(static_margin) and static_margin >= 0):
        raise SensorlessError(f"--static-margin must be ≥ 0, got {static_margin}")
    if warmup is not None and not (np.isfinite(warmup) and warmup >= 0):
        raise SensorlessError(f"--warmup must be ≥ 0 seconds, got {warmup}")
    try:
        TrimWindow.parse(quiet)  # checked here, used by the monitor
    except DataError:
        raise SensorlessError(f"--quiet must be START:END in seconds after the first sample (e.g. 0:2, ':2', "
                              f"'abs:T0:T1' for the log's stamps), got '{quiet}'") from None
    names = monitored_rows(dyn)[0]
    fs_spec = _parse_static_friction(static_friction, names)
    speed: object = "auto"
    if rest_speed.strip().lower() != "auto":
        speed = _nonnegative(rest_speed, f"--rest-speed must be 'auto' or a speed in rad/s, got '{rest_speed}'",
                             f"--rest-speed must be ≥ 0 rad/s, got '{rest_speed}'")
    settings = MonitorSettings(quiet=quiet.strip(), k=k, false_alarm_rate=false_alarm_rate, gain=gain, order=order,
                               static_friction=fs_spec if isinstance(fs_spec, str) else tuple(map(float, fs_spec)),
                               static_margin=static_margin, rest_speed=speed, warmup=warmup,
                               min_duration=min_duration, merge_gap=merge_gap)
    with atomic_outdir(out, force, inputs=path_inputs(robot, model, data)) as tmp:
        (traj,), opts = ((bench_log,), {}) if bench else model_logs(art, [data], r, prep)
        mon = monitor_log(dyn, traj, settings, savgol_window=opts.get("savgol_window"))
        t, th, trace, tau_ext = mon.t, mon.thresholds, mon.trace, mon.tau_ext
        flag, intervals, band_ivs = mon.contact, mon.contacts, mon.static_band
        arrays = {"t": t, "tau_ext": tau_ext, "r_raw": mon.raw, "holding": trace.holding, "status": trace.status,
                  "status_names": np.array(STATUS), "rest": trace.rest, "contact": flag, "joints": np.array(names),
                  "r": mon.observer.r, "coordinates": np.array(mon.observer.names)}
        doc = {
            "data": str(data), "model": str(path), "model_origin": None if bench else art.origin,
            "model_label": "friction-only model" if bench else art.label, "robot": None if bench else r.name,
            "rows": names, "projected": mon.monitored is not None and mon.monitored.projector is not None,
            "observer": mon.observer.settings,
            "settings": {**mon.settings, "static_friction": static_friction, "frame": frame,
                         "reference": str(reference) if frame else None,
                         "preprocessing": {kk: vv for kk, vv in opts.items() if kk != "gains"}},
            "thresholds": th.to_dict(),
            "noise": {"torque_sigma_rest": dict(zip(names, th.sigma_rest.tolist())),
                      "torque_sigma_moving": dict(zip(names, th.sigma_move.tolist()))},
            "contacts": [_interval_doc(iv, names, t[0], "contact") for iv in intervals],
            "static_band": [_interval_doc(iv, names, t[0], "static_band") for iv in band_ivs],
            "peak_external_torque": {n: float(tau_ext[:, j][np.nanargmax(np.abs(tau_ext[:, j]))]) for j, n in enumerate(names)},
            "contact_fraction": float(flag.mean()),
            "rest_fraction": dict(zip(names, trace.rest.mean(axis=0).tolist())),
            "static_band_fraction": float(((trace.status == STATUS.index("static_band")).any(axis=1) & ~flag).mean()),
        }
        mask = mon.quiet
        warm = mon.settings["warmup_s"]
        if frame:
            warm_rows = np.isnan(tau_ext).any(axis=1)  # the observer's warm-up: no estimate
            mt = MonitoredTorque(np.where(warm_rows[:, None], 0.0, tau_ext), names, mon.monitored.rows,
                                 mon.monitored.projector)
            fe = cartesian_force(dyn, traj, mt, frame, reference)
            fe.F[warm_rows] = np.nan
            arrays.update({"force": fe.F, "force_labels": np.array(fe.labels), "sigma_min": fe.sigma_min,
                           "force_unobservable": fe.arrays()["unobservable"]})
            doc["frame"] = {"name": frame, "reference": reference, "labels": fe.labels}
            Fq = fe.F[mask]
            nq = np.linalg.norm(Fq, axis=1)
            doc["noise"]["force_rms_quiet"] = float(np.sqrt(np.nanmean(nq**2))) if np.isfinite(nq).any() else None
            doc["noise"]["force_sigma_quiet"] = [  # a component never observable in the window: None
                float(np.nanstd(c)) if np.isfinite(c).sum() > 1 else None for c in Fq.T] if np.isfinite(Fq).any() else None
            for ivs, docs in ((intervals, doc["contacts"]), (band_ivs, doc["static_band"])):
                for iv, d in zip(ivs, docs):
                    d.update(_peak_force(fe.F, t, iv))
        from ..io import jsonable

        (tmp / "monitor.json").write_text(json.dumps(jsonable(doc), indent=2, allow_nan=False))
        np.savez(tmp / "monitor.npz", **arrays)
        if plot:
            from ..report.monitor_plot import plot_monitor

            plot_monitor(mon, tmp, robot=r, title=f"{Path(data).name}: external torque, {doc['model_label'].split(':')[0]} model")
    console.print(f"model: {doc['model_label']}" + ("; external torque projected by the contacts, P(q) r"
                                                     if doc["projected"] else ""), highlight=False, soft_wrap=True)
    console.print(f"observer order {order}, K = {gain:g} 1/s, warm-up {warm:.3f} s; k = {th.k:.2f} σ from "
                  f"{int(mask.sum())} quiet samples (--quiet {quiet.strip()})")
    for n, fsj, src in zip(names, th.band, th.band_source):
        console.print(f"  {safe(n)}: static band ±{fsj:.3g} N·m ({src}); σ rest {th.sigma_rest[names.index(n)]:.3g} N·m")
    for iv, d in zip(intervals, doc["contacts"]):
        f = (f", |F| peak {d['peak_force_norm']:.1f} N at {d['peak_force_time'] - t[0]:.2f} s"
             if frame and d.get("peak_force_norm") is not None else ", |F| unobservable at this frame" if frame else "")
        rest_j = [f"{j} at rest, ≥ {iv.band_excess[j]:.3g} N·m beyond the static band" for j in iv.joints
                  if iv.state.get(j) == "rest"]
        jp = int(np.argmax(np.abs(iv.peak)))
        console.print(f"contact {iv.start - t[0]:8.3f} – {iv.end - t[0]:8.3f} s  joints {safe(','.join(iv.joints))}, "
                      f"peak τ_ext {iv.peak[jp]:.3g} N·m ({names[jp]}){f}"
                      + (f" ({'; '.join(rest_j)})" if rest_j else ""))
    if band_ivs:
        console.print(f"{len(band_ivs)} interval(s) at rest where the external torque is indistinguishable from static "
                      "friction (not contacts; 'static_band' in monitor.json)")
    console.print(f"{len(intervals)} contact interval(s); times in s after the first sample; wrote {safe(out)}/")


def _interval_doc(iv, names: list[str], t0: float, dead_zone: str) -> dict:
    """An interval for monitor.json: stamps and seconds after the first sample, peak τ_ext per joint, and at rest
    the dead-zone status."""
    d = iv.to_dict()
    d.update(start_s=iv.start - t0, end_s=iv.end - t0, peak_external_torque=dict(zip(names, iv.peak)))
    if dead_zone == "contact":
        d["dead_zone"] = {j: ("moving: identified friction, no dead zone" if iv.state.get(j) == "moving" else
                              f"at rest: outside the static-friction band by {iv.band_excess.get(j, float('nan')):.4g} N·m")
                          for j in iv.joints}
    else:
        d["dead_zone"] = {j: "at rest: inside the static-friction band, indistinguishable from static friction"
                          for j in iv.joints}
    return d


def _peak_force(F: np.ndarray, t: np.ndarray, iv) -> dict:
    import numpy as np
    seg = F[iv.start_index : iv.end_index + 1]
    norm = np.linalg.norm(seg, axis=1)  # NaN on samples with an unobservable component
    if not np.any(np.isfinite(norm)):
        return {"peak_force": None, "peak_force_norm": None, "peak_force_time": None}
    i = int(np.nanargmax(norm))
    return {"peak_force": seg[i].tolist(), "peak_force_norm": float(norm[i]), "peak_force_time": float(t[iv.start_index + i])}

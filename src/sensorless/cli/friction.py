"""`sensorless friction`: a friction-only model from test-bench logs (no robot model).

Reads one or more logs of one or more joints (t, q and/or v, τ or currents with --gains) at their
own time stamps (:mod:`sensorless.data.bench_log`: irregular steps are kept, gaps only split the
differentiation), fits per joint the static law and the friction state and keeps the optional terms
and the state where the blocked held-out error across the training logs supports them
(:mod:`sensorless.identification.friction_fit`), reports the terms with 95 % intervals and, on --test
logs, the error overall and near velocity reversals and pooled per group of test logs
(``--test GROUP=FILE``), and writes a model folder (result.json;
:func:`~sensorless.identification.artifact.save_friction_model`) that `sensorless predict` reads without
--robot, and friction.png.

A bench that logs the motor current (or input torque) *and* an output torque (``tau_out``) is fitted as
a drive: the gain K is estimated with the friction, and the model predicts the output torque from the
current. Two reference fits are made in the same run on the same logs and reported next to it: the
linear current fit K u + o and the linear fit with Coulomb and viscous friction.
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import DataError, OptionError
from .common import (
    MultiValueCommand,
    app,
    atomic_outdir,
    gains_option,
    guarded,
    log_reading_options,
    path_inputs,
    force_option,
    time_unit_option,
)
from .console import console, safe
from .logs import trim_option
from .options import FrictionState, TimeUnit, Velocity
from .progress import progress_bars

__all__ = ["drive_gains_of", "friction", "friction_model_log", "predict_friction", "read_bench_logs"]

#: the preprocessing keys a friction model stores (settings.preprocessing) and predict reuses
BENCH_KEYS = ("columns", "gains", "rate", "time_unit", "max_gap", "velocity", "savgol_window", "angle_unit", "flip")
#: the reference fits of a drive bench (name, terms), made with the state off
DRIVE_REFERENCES = (("linear K·u + o", ("offset",)), ("linear + Coulomb/viscous", ("fc", "fv", "offset")))


def read_bench_logs(paths, prep: dict, *, joints=None, need_acceleration: bool = True) -> list:
    """Bench logs (:func:`~sensorless.data.bench_log.read_bench_log`) with the options ``prep``
    (:data:`BENCH_KEYS` and ``trim``)."""
    from ..data.prepare import check_preprocessing, parse_columns

    check_preprocessing(prep.get("rate"), None, prep.get("savgol_window"), 1)
    cols = prep.get("columns")
    cols = parse_columns(cols) if isinstance(cols, str) else cols
    gap = prep.get("max_gap")
    from ..data.limits import current_options, read_options

    with read_options(angle_unit=prep.get("angle_unit")):  # --angle-unit, or the model's
        return _read_bench_logs(paths, prep, cols, gap, joints, need_acceleration)


def _read_bench_logs(paths, prep: dict, cols, gap, joints, need_acceleration: bool) -> list:
    from ..data.bench_log import DEFAULT_BENCH_GAP, read_bench_log

    return [read_bench_log(p, columns=cols, joints=joints, gains=prep.get("gains"), rate=prep.get("rate"),
                           time_unit=None if prep.get("time_unit") is None else str(prep["time_unit"]),
                           trim=prep.get("trim"), max_gap=DEFAULT_BENCH_GAP if gap is None else float(gap),
                           velocity=str(prep.get("velocity") or "logged"), savgol_window=prep.get("savgol_window"),
                           need_acceleration=need_acceleration, flip=tuple(prep.get("flip") or ())) for p in paths]


def _test_groups(test: "list[str]") -> "tuple[list[Path], list[str]]":
    """``--test`` values as (paths, group of each): ``GROUP=FILE`` names the group, a bare FILE (or one
    that exists as written) is in the group "held-out"."""
    paths, groups = [], []
    for item in test:
        item = str(item)
        if "=" in item and not Path(item).exists():
            g, p = item.split("=", 1)
            groups.append(g.strip() or "held-out")
            paths.append(Path(p.strip()))
        else:
            groups.append("held-out")
            paths.append(Path(item))
    return paths, groups


@app.command("friction", cls=MultiValueCommand)
@guarded
@log_reading_options()
def friction(
    data: List[Path] = typer.Option(..., help="bench log(s) to fit (.csv .npz .parquet .h5): time, position and/or "
                                              "velocity, torque (or currents with --gains) per joint; a single-joint "
                                              "CSV may have bare columns t,q,v,tau"),
    test: List[str] = typer.Option([], help="held-out log(s): RMSE overall and near velocity reversals; "
                                            "GROUP=FILE puts the log in a group whose RMSE is pooled"),
    out: Path = typer.Option(Path("friction_model"), help="output folder: result.json (a model for `sensorless "
                                                          "predict`), friction.png, and for a drive gains.json "
                                                          "(for --gains; written atomically)"),
    joints: Optional[str] = typer.Option(None, help="joints to fit, comma-separated (default: every joint of the "
                                                    "first log); the name of the joint of a bare-column log"),
    terms: str = typer.Option("fc,stribeck,fv,offset,inertia,gain_back,load,stiffness",
                              help="linear terms among fc, stribeck, damping, fv, offset, inertia (J v̇), gain_back "
                                   "(a drive's gain differs when back-driven), load (Coulomb growing with the "
                                   "output torque) and stiffness (an elastic transmission, with q_motor logged); "
                                   "stribeck, damping, gain_back, load, stiffness and the state are kept only where "
                                   "the held-out error across the training logs supports them"),
    state: FrictionState = typer.Option(FrictionState.auto, help="friction state (presliding, hysteresis): auto "
                                                                 "(kept where held-out error supports it) | on | off"),
    flip: Optional[str] = typer.Option(None, help="reverse the sign of fields a sensor counts the other way, "
                                                  "comma-separated among q, tau, current, tau_out, q_motor"),
    coulomb_smoothing: str = typer.Option("auto", help="ε of the static law's tanh(v/ε): auto (3 velocity-noise "
                                                       "stds) or a number [rad/s]"),
    columns: Optional[str] = typer.Option(None, help="column map, e.g. 'q=pos_{joint};v=vel_{joint};tau=trq_{joint}'"),
    gains: Optional[str] = gains_option(),
    rate: Optional[float] = typer.Option(None, help="sample rate [Hz] for logs without a time column"),
    time_unit: Optional[TimeUnit] = time_unit_option(),
    trim: Optional[str] = trim_option(),
    max_gap: float = typer.Option(10.0, help="a time step over this many median periods splits a log for "
                                             "differentiation (reported, never refused; steps are not resampled)"),
    velocity: Velocity = typer.Option(Velocity.logged, help="logged (keep a logged v) | from-q (v from q)"),
    savgol_window: Optional[int] = typer.Option(None, help="Savitzky-Golay window [samples] for derivatives "
                                                           "(default 0.2 s)"),
    reversal_window: float = typer.Option(1.0, help="seconds on each side of a velocity reversal counted as near it"),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write friction.png"),
    force: bool = force_option(),
) -> None:
    """Identify joint friction from test-bench logs, without a robot model: static law (Coulomb,
    Stribeck, viscous, offset, inertia) or a Dahl/LuGre-type state for presliding and hysteresis,
    chosen per joint on blocked held-out error; with a current and an output torque logged, the drive
    gain (and its back-driven gain, a load-dependent Coulomb term) with the friction; terms with 95 %
    intervals; held-out error near reversals and per group of test logs."""
    import numpy as np
    from ..identification.artifact import save_friction_model
    from ..identification.friction_fit import DEFAULT_TERMS
    from ..identification.friction_model import FrictionModel

    smoothing = _smoothing(coulomb_smoothing)
    if not (np.isfinite(reversal_window) and reversal_window > 0):
        raise OptionError(f"--reversal-window must be > 0 s, got {reversal_window}")
    from ..data.limits import current_options

    term_list = tuple(t.strip() for t in terms.split(",") if t.strip()) or DEFAULT_TERMS
    names = [j.strip() for j in joints.split(",") if j.strip()] if joints else None
    flips = [f.strip() for f in flip.split(",") if f.strip()] if flip else []
    test_paths, groups = _test_groups(test)
    prep = {"columns": columns, "gains": gains, "rate": rate, "time_unit": time_unit, "max_gap": max_gap,
            "velocity": str(velocity), "savgol_window": savgol_window, "trim": trim,
            "angle_unit": current_options().get("angle_unit") or "rad", "flip": flips or None}
    test = test_paths
    with atomic_outdir(out, force, inputs=path_inputs(data, test)) as tmp:
        need_a = "inertia" in term_list
        one = names if names and len(names) == 1 else None  # names the joint of a bare-column log
        train = read_bench_logs(data, prep, joints=one, need_acceleration=need_a)
        held = read_bench_logs(test, prep, joints=one, need_acceleration=need_a)
        from ..data.integrity import bench_torque_problem

        for p, tr in zip([*data, *test], [*train, *held]):
            why = bench_torque_problem(tr)
            if why:
                raise DataError(f"{p}: {why}")
        with progress_bars() as bars:
            model = FrictionModel(term_list, str(state), smoothing, joints=names).fit(
                train, progress=bars.callback("friction laws (joints)"))
        refs = _references(model, train, smoothing, names)
        validation = {str(p): _errors(model, tr, reversal_window, refs) for p, tr in zip(test, held)}
        training = {str(p): _errors(model, tr, reversal_window, refs) for p, tr in zip(data, train)}
        pooled = _pooled(validation, groups) if validation else {}
        doc = {"settings": {"data": [str(p) for p in data], "test": [str(p) for p in test],
                            "reversal_window": reversal_window,
                            "preprocessing": {k: (None if prep[k] is None else
                                                  str(prep[k]) if k in ("time_unit", "velocity") else prep[k])
                                              for k in BENCH_KEYS} | {"trim": trim},
                            "signals": {str(p): tr.provenance for p, tr in zip([*data, *test], [*train, *held])}},
               "diagnostics": {j: {k: v for k, v in f.to_dict().items() if k not in ("law", "static")}
                               for j, f in model.fits_.items()},
               "training": training, "validation": validation, "validation_groups": pooled,
               "references": {name: {j: law.to_dict() for j, law in ref.laws_.items()} for name, ref in refs.items()}}
        resolved = next((t.provenance["gains"] for t in train if "gains" in t.provenance), None)
        if resolved is not None:
            doc["settings"]["preprocessing"]["gains"] = resolved
        save_friction_model(tmp, model, doc)
        gains = drive_gains_of(model)
        if gains is not None:
            from ..io import write_json_atomic

            write_json_atomic(gains, tmp / "gains.json")
        if plot:
            from ..report.friction_bench_plot import plot_bench_friction

            plot_bench_friction(model, held or train, tmp / "friction.png", window=reversal_window,
                                title=f"friction per joint ({'held-out' if held else 'training'} log)")
    _print(model, validation or training, bool(validation))
    if pooled:
        _print_pooled(pooled)
    console.print(f"wrote {out}/")


def _smoothing(text: str):
    import numpy as np
    if text == "auto":
        return "auto"
    try:
        val = float(text)
    except ValueError:
        val = float("nan")
    if not (np.isfinite(val) and val >= 0):
        raise OptionError(f"--coulomb-smoothing must be 'auto' or a number >= 0 [rad/s], got '{text}'")
    return val


def drive_gains_of(model) -> "dict | None":
    """The drive gains K of a model whose laws are drives, as a gains file (``--gains gains.json``
    elsewhere): ``{"gains": {joint: K}}`` for the joints whose K has a 95 % interval clear of 0, the
    intervals, the back-driven gains, and the joints left out with the reason; None for a plain model."""
    if not model.laws_ or not all(law.is_drive for law in model.laws_.values()):
        return None
    out = {"gains": {}, "intervals": {}, "gain_back": {}, "undetermined": {},
           "source": "sensorless friction (gain fitted with the friction from the current and the output torque)"}
    for j, law in model.laws_.items():
        iv = model.fits_[j].intervals.get("gain") if model.fits_ else None
        if iv is None or iv[0] <= 0 <= iv[1]:
            out["undetermined"][j] = (f"K = {law.coef['gain']:.4g}, 95 % interval {iv} includes 0 (another term, "
                                      "e.g. the stiffness, carries the torque)")
            continue
        out["gains"][j], out["intervals"][j] = law.coef["gain"], iv
        if "gain_back" in law.coef:
            out["gain_back"][j] = law.coef["gain"] + law.coef["gain_back"]
    return out


def _references(model, train: list, smoothing, names) -> dict:
    """The reference fits of a drive bench (:data:`DRIVE_REFERENCES`) on the training logs, or {}."""
    from ..identification.friction_model import FrictionModel

    if not all(law.is_drive for law in model.laws_.values()):
        return {}
    return {name: FrictionModel(terms, "off", smoothing, joints=names).fit(train) for name, terms in DRIVE_REFERENCES}


def _errors(model, traj, window: float, refs: "dict | None" = None) -> dict:
    """Per joint: the chosen and the best static law's RMSE overall and near reversals (and each
    reference fit's, :func:`_references`)."""
    from ..identification.friction_model import friction_errors, measured_torque

    pred, stat = model.predict(traj), model.predict(traj, static=True)
    others = {name: ref.predict(traj) for name, ref in (refs or {}).items()}
    out = {}
    for k, j in enumerate(model.joint_names_):
        c = list(traj.joint_names).index(j)
        args = (traj.t, traj.v[:, c])
        y = measured_torque(traj, j)
        out[j] = {"chosen": model.laws_[j].kind,
                  "model": friction_errors(y, pred[:, k], *args, window=window),
                  "static": friction_errors(y, stat[:, k], *args, window=window)}
        for name, p in others.items():
            out[j].setdefault("references", {})[name] = friction_errors(y, p[:, k], *args, window=window)
    return out


def _pooled(errors: dict, groups: "list[str]") -> dict:
    """Per group of test logs and joint: the RMSE pooled over the group's samples, of the model, the
    best static law and each reference fit."""
    out: dict = {}
    for (log, per), g in zip(errors.items(), groups):
        for j, e in per.items():
            acc = out.setdefault(g, {}).setdefault(j, {"logs": 0})
            acc["logs"] += 1
            for name, m in [("model", e["model"]), ("static", e["static"])] + list(e.get("references", {}).items()):
                ss, n = acc.get(name, (0.0, 0))
                acc[name] = (ss + m["rmse"] ** 2 * m["n_samples"], n + m["n_samples"])
    return {g: {j: {k: (float((v[0] / v[1]) ** 0.5) if isinstance(v, tuple) else v) for k, v in acc.items()}
                for j, acc in per.items()} for g, per in out.items()}


def _print_pooled(pooled: dict) -> None:
    from rich.table import Table

    names = sorted({k for per in pooled.values() for acc in per.values() for k in acc if k not in ("logs",)},
                   key=lambda k: (k != "model", k != "static", k))
    t = Table(title="held-out RMSE pooled per group of test logs")
    for col in ["group", "joint", "logs"] + [("best static law" if n == "static" else n) for n in names]:
        t.add_column(col, justify="right")
    for g, per in pooled.items():
        for j, acc in per.items():
            t.add_row(g, j, str(acc["logs"]), *[_fmt(acc.get(n)) for n in names])
    console.print(t)


_LABELS = {"stribeck": "fs − fc", "gain": "gain K", "gain_back": "ΔK (back-driven)", "load": "μ (× |τ_out|)",
           "stiffness_motor": "k_m (× q_motor)", "stiffness_out": "k_o (× q)"}


def _fmt(x) -> str:
    return "–" if x is None else f"{x:.4g}"


def _print(model, errors: dict, held_out: bool) -> None:
    from rich.table import Table

    for j in model.joint_names_:
        fit, law = model.fits_[j], model.laws_[j]
        t = Table(title=f"{safe(j)}: {law.kind} law — {safe(fit.reason)}")
        for col in ("term", "value", "95 % interval"):
            t.add_column(col, justify="right")
        for term, val in law.coef.items():
            iv = fit.intervals[term]
            t.add_row(_LABELS.get(term, term), f"{val:.4g}",
                      "at its bound 0" if iv is None else f"[{iv[0]:.4g}, {iv[1]:.4g}]")
        if law.vs:
            t.add_row("vs", f"{law.vs:.4g}", "(grid)")
        if law.kind == "state":
            lo, hi = fit.presliding_interval or (None, None)
            t.add_row("presliding 1/k", f"{1 / law.k:.4g}", f"[{_fmt(lo)}, {_fmt(hi)}]")
        else:
            how = "(grid, from the noise up)" if model.coulomb_smoothing == "auto" else "(given)"
            t.add_row("ε (tanh)", f"{law.eps:.4g}", how)
        console.print(t)
    t = Table(title=("held-out" if held_out else "training") + " RMSE: overall / near reversals")
    for col in ("log", "joint", "law", "model", "best static law"):
        t.add_column(col, justify="right")
    for log, per in errors.items():
        for j, e in per.items():
            m, s = e["model"], e["static"]
            t.add_row(safe(Path(log).name), safe(j), e["chosen"], f"{_fmt(m['rmse'])} / {_fmt(m['rmse_reversals'])}",
                      f"{_fmt(s['rmse'])} / {_fmt(s['rmse_reversals'])}")
    console.print(t)


def friction_model_log(model: Path, data: Path, prep: dict, *, need_acceleration: "bool | None" = None):
    """A friction-only model (:func:`~sensorless.identification.artifact.load_friction_model`) and a log
    read as its training logs were (each option in ``prep`` given wins): ``(artifact, trajectory, options)``."""
    from ..identification.artifact import load_friction_model

    art = load_friction_model(model)
    from ..data.limits import current_options

    prep = {"angle_unit": current_options().get("angle_unit"), **prep}  # --angle-unit (log_reading_options)
    bad = [f"--{k}" for k in ("lowpass", "resample") if prep.get(k) is not None]
    if bad:
        raise OptionError(f"{' and '.join(bad)} {'does' if len(bad) == 1 else 'do'} not apply to a friction-only "
                          "model (its logs are neither filtered nor resampled)")
    opts = {k: prep.get(k) if prep.get(k) is not None else art.preprocessing.get(k) for k in BENCH_KEYS}
    opts["trim"] = prep.get("trim")
    joints = list(art.model.joint_names_)
    if need_acceleration is None:
        need_acceleration = any("inertia" in law.coef for law in art.model.laws_.values())
    (traj,) = read_bench_logs([data], opts, joints=joints if len(joints) == 1 else None,
                              need_acceleration=need_acceleration)
    return art, traj, opts


def predict_friction(model: Path, data: Path, out: Path, prep: dict) -> None:
    """`sensorless predict` with a friction-only model: τ̂ of the log (states from zero), the
    measured τ, the best static law's τ̂ when the model has a state; metrics overall and near reversals."""
    import json

    import numpy as np

    from ..identification.metrics import torque_metrics
    from ..io import write_npz_atomic
    from ..report import metrics_table

    art, traj, opts = friction_model_log(model, data, prep)
    fm = art.model
    joints = list(fm.joint_names_)
    pred = fm.predict(traj)
    if not np.all(np.isfinite(pred)):
        raise OptionError(f"{art.path}: the friction model predicts non-finite torques on {data}")
    from ..identification.friction_model import measured_torque

    meas = np.column_stack([measured_torque(traj, j) for j in joints])
    arrays = {"t": traj.t, "tau_pred": pred, "joints": np.array(joints), "tau_measured": meas,
              "preprocessing": np.array(json.dumps({**{k: None if v is None else str(v) if k in ("time_unit", "velocity")
                                                      else v for k, v in opts.items()},
                                                   "signals": traj.provenance}, default=str))}
    rows = {"model": torque_metrics(meas, pred, joints)}
    if fm.has_state and fm.static_laws_:
        arrays["tau_pred_static"] = fm.predict(traj, static=True)
        rows["best static law"] = torque_metrics(meas, arrays["tau_pred_static"], joints)
    console.print(metrics_table(Path(data).name, rows))
    window = float(art.doc.get("settings", {}).get("reversal_window", 1.0) or 1.0)
    _print_reversals(fm, {str(data): _errors(fm, traj, window)} if fm.static_laws_ else {}, window)
    write_npz_atomic(out, **arrays)
    console.print(f"wrote {out}")


def _print_reversals(model, errors: dict, window: float) -> None:
    from rich.table import Table

    if not errors:
        return
    t = Table(title=f"RMSE near velocity reversals (± {window:g} s)")
    for col in ("joint", "law", "model", "best static law", "samples"):
        t.add_column(col, justify="right")
    for per in errors.values():
        for j, e in per.items():
            t.add_row(j, e["chosen"], _fmt(e["model"]["rmse_reversals"]), _fmt(e["static"]["rmse_reversals"]),
                      str(e["model"]["samples_near_reversals"]))
    console.print(t)

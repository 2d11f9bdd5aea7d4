"""Core commands: identify, predict, demo, benchmark identify."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from ..errors import ExcitationError, OptionError, SensorlessError
from ..io import write_npz_atomic
from .common import (
    ROBOT_HELP,
    MultiValueCommand,
    app,
    atomic_outdir,
    bench_app,
    check_preprocessing,
    console,
    err_console,
    gains_option,
    guarded,
    load_logs,
    load_robot_arg,
    max_gap_option,
    model_preprocessing,
    output_file,
    path_inputs,
    preprocessing_settings,
    progress_bar,
    resample_option,
    trim_option,
    velocity_option,
)



@app.command(cls=MultiValueCommand)
@guarded
def identify(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    data: List[Path] = typer.Option(..., help="training log(s): .csv .npz .parquet .h5, ROS .bag / .mcap / ROS 2 bag "
                                         "folder; several after one flag (--data a.csv b.csv) or repeated"),
    validate: List[Path] = typer.Option([], help="held-out log(s) to report metrics on (several after one flag too)"),
    method: str = typer.Option("ols", help="ols | wls | lmi (physically consistent) | svd"),
    prior: Optional[Path] = typer.Option(None, help="lmi: URDF whose inertials are the prior (default: --robot's own)"),
    regularization: str = typer.Option("pullback", help="lmi: pullback | entropic | euclidean | none"),
    gamma: str = typer.Option("auto", help="lmi: regularisation weight, or 'auto' (5-fold cross-validation)"),
    ellipsoids: str = typer.Option("auto", help="lmi: bounding ellipsoids auto | kinematic | none"),
    contain_prior: bool = typer.Option(True, help="lmi: grow each ellipsoid to contain any body near the prior "
                                       "(second moments ×4, CoM within 7.5 cm); --no-contain-prior: geometry only"),
    weights: str = typer.Option("auto", help="per-joint noise weighting, every method: auto (two-step: σ from an "
                                "unweighted fit's residual) | none | FILE (JSON {joint: σ} or CSV 'joint,σ' rows)"),
    out: Path = typer.Option(..., help="output directory (written atomically)"),
    joint_terms: str = typer.Option("fv,fc,offset,armature", help="joint terms fv,fc,stribeck,offset,armature for every "
                                    "joint, or per joint 'JOINT=fv,fc,offset;JOINT=fv;*=fv,fc' ('*': the joints not "
                                    "listed, else none) (dvrk_psm: drive set 'authors' (default) or 'motors')"),
    columns: Optional[str] = typer.Option(None, help="column map, e.g. 'q=0:7;v=7:14;tau=14:21' or 'q=pos_{joint}'"),
    rate: Optional[float] = typer.Option(None, help="sample rate [Hz] for logs without a time column"),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off [Hz] before identification"),
    savgol_window: Optional[int] = typer.Option(None, help="Savitzky-Golay window: re-derive v̇ from the logged v "
                                                       "(v and v̇ from q when v is not logged)"),
    decimate: int = typer.Option(1, help="keep every n-th sample (after anti-alias filtering)"),
    gains: Optional[str] = gains_option(),
    trim: Optional[str] = trim_option(),
    resample: str = resample_option(),
    velocity: str = velocity_option(),
    max_gap: Optional[float] = max_gap_option(),
    lock: Optional[List[str]] = typer.Option(None, help="joints to lock (e.g. gripper fingers)"),
    floating_base: Optional[bool] = typer.Option(None, "--floating-base/--fixed-base"),
    contact_frames: Optional[str] = typer.Option(
        None, help="legged robots: comma-separated contact frames (feet); projects out the unknown contact "
                   "forces, flags from the log's 'contact' columns or detected from foot height/speed"),
    contact_dims: Optional[str] = typer.Option(None, help="per contact frame 3 (point foot) or 6 (flat foot); default 3"),
    contact_offset: float = typer.Option(0.0, help="radius [m] of spherical feet (contact point below the frame)"),
    contact_mode: str = typer.Option("projected", help="projected (no force sensing) | wrench (log has contact_forces)"),
    contact_rows: str = typer.Option("auto", help="wrench mode: base (6 floating-base rows; logs without joint "
                                     "torques) | all (+ torque rows) | auto (base when the logs have no torques)"),
    wrench_offset: str = typer.Option("none", help="wrench mode: constant wrench bias to identify: none | net | "
                                      "foot (world axes, per foot) | sole (force in each sole frame)"),
    offset_axes: str = typer.Option("xy", help="force axes of --wrench-offset (xyz adds the vertical one, "
                                    "confounded with m·g on standing data)"),
    imu_frame: Optional[str] = typer.Option(None, help="model frame of the accelerometer ('imu_acc'): rotation and "
                                            "lever arm from the model, on any body (e.g. imu_link)"),
    coulomb_smoothing: str = typer.Option("auto", help="ε [rad/s] of the Coulomb term tanh(v/ε); 0 = sgn(v); auto: 3 × "
                                          "the joint's velocity noise (docs/arm.md §7)"),
    rest: str = typer.Option("auto", help="auto: a joint whose logged |v| stays within 5 noise stds of 0 over the "
                             "derivative window is at rest, v = v̇ = 0 there (no friction chatter at rest; the model "
                             "remembers it) | off (docs/arm.md §7)"),
    stribeck_velocity: str = typer.Option("auto", help="vs [rad/s] of the 'stribeck' term: a number, or auto (1-D search "
                                          "per joint)"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
    outliers: str = typer.Option("error", help="gross outliers in a log (robust MAD test): error | drop (with a "
                                               "warning) | keep"),
    scheduler: Optional[str] = typer.Option(
        None, help="compress on Dask: 'local' (a LocalCluster on this machine) or a scheduler address "
                   "tcp://HOST:PORT; workers read the --data files themselves (see docs/fleet.md)"),
    workers: Optional[int] = typer.Option(None, help="--scheduler local: worker processes (default: one per core); "
                                                     "an address: wait until this many workers are connected"),
    skip_bad: bool = typer.Option(False, help="skip unreadable/invalid --data files (listed in result.json) instead of failing"),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write torques.png (a decimated window of the first "
                              "held-out log, else of the first training log)"),
) -> None:
    """Identify a dynamic model from logs; write result.json, model.urdf, joint_terms.json, torques.png, report.html.

    --data accepts glob patterns, '**' recursive (quote them: --data 'logs/**/*.parquet')."""
    from ..estimators import CADModel
    from ..identification import identify as _identify
    from ..report import metrics_table

    coulomb_smoothing, stribeck_velocity = _friction_options(coulomb_smoothing, stribeck_velocity)
    _check_identify_options(method, gamma, regularization, coulomb_smoothing, outliers, weights)
    check_preprocessing(rate, lowpass, savgol_window, decimate)
    if workers is not None and scheduler is None:
        raise OptionError("--workers needs --scheduler (local or tcp://HOST:PORT)")
    if scheduler is not None and (imu_frame or contact_mode == "wrench"):
        raise OptionError("--scheduler does not support --imu-frame or --contact-mode wrench yet; run without it")
    if floating_base is None and contact_frames:
        floating_base = True  # contact structures need a floating base; a URDF would load fixed
    r = load_robot_arg(robot, lock, floating_base)
    from ..regressor.distributed import LogReader, expand_paths

    data = [Path(p) for p in expand_paths(data)]
    prep = dict(columns=columns, rate=rate, lowpass=lowpass, savgol_window=savgol_window, decimate=decimate,
                gains=gains, trim=trim, resample=resample, velocity=velocity, max_gap=max_gap, outliers=outliers,
                rest=rest)
    with atomic_outdir(out, force, inputs=path_inputs(robot, data, validate, prior, weights)) as tmp:
        skipped: list = []
        if scheduler is None:
            train, data, skipped = _load_training(data, r, prep, skip_bad)
        val = load_logs(validate, r, **prep)
        if imu_frame:
            train, val = (_imu_frame_logs(logs, r, imu_frame, savgol_window) for logs in (train, val))
        structure = _structure(r, joint_terms, 0.0 if coulomb_smoothing == "auto" else coulomb_smoothing, contact_frames, contact_dims, contact_offset,
                               contact_mode, contact_rows=contact_rows, wrench_offset=wrench_offset,
                               offset_axes=offset_axes, train=train if scheduler is None else None)
        lmi_kw = _lmi_kwargs(r, structure, method, prior, regularization, gamma, ellipsoids, contain_prior)
        from ..identification.weights import weights_option

        row_sigma = weights_option(weights, structure.row_names)
        fleet = None
        if scheduler is not None:
            from .fleet import identify_on_dask

            result, fleet = identify_on_dask(structure, data, scheduler, workers, LogReader(**prep), method, skip_bad,
                                             {**lmi_kw, "weights": row_sigma})
            data, skipped = [Path(p) for p in fleet.files], fleet.skipped
            train = _first_training_log(data, r, prep) if not val else []
        else:
            total = sum(len(t) for t in train)
            friction = _plain(structure) and (coulomb_smoothing == "auto" or "stribeck" in structure.joint_terms)
            with progress_bar() as bar:
                task = bar.add_task("regressor", total=total * (2 if friction else 1))
                kw = dict(method=method, progress=lambda n: bar.advance(task, n), outliers="keep", weights=row_sigma,
                          **lmi_kw)
                try:  # the logs' outliers were handled on reading
                    if friction:
                        from ..identification.friction import identify_friction

                        raw = (load_logs(data, r, **{**prep, "lowpass": None})
                               if lowpass and coulomb_smoothing == "auto"
                               else None)  # noise is measured before the low-pass colours it
                        result, fit = identify_friction(structure, train, coulomb_smoothing=coulomb_smoothing,
                                                        stribeck_velocity=stribeck_velocity, identify_kwargs=kw,
                                                        noise_logs=raw, lowpass_hz=lowpass)
                        structure = result.structure
                        result.settings["friction"] = fit.to_dict()
                    else:
                        result = _identify(structure, train, **kw)
                except ExcitationError as exc:
                    raise ExcitationError(f"{', '.join(map(str, data))}: {exc}") from None
        result.settings.update({"data": [str(p) for p in data], "validate": [str(p) for p in validate],
                                "lowpass_hz": lowpass, "savgol_window": savgol_window, "decimate": decimate,
                                "columns": columns, "rate": rate,
                                "preprocessing": preprocessing_settings(
                                    train + val, columns=columns, gains=gains, rate=rate, trim=trim,
                                    resample=resample, lowpass=lowpass, savgol_window=savgol_window,
                                    velocity=velocity, decimate=decimate, max_gap=max_gap, rest=rest),
                                "signals": {str(p): t.provenance for p, t in zip([*data, *validate], [*train, *val])}
                                if scheduler is None else {str(p): t.provenance for p, t in zip(validate, val)}})
        if scheduler is not None or skip_bad:
            result.settings.update({"scheduler": scheduler, "skipped_files": [{"file": f, "error": e} for f, e in skipped]})
        for f, e in skipped:
            err_console.print(f"[yellow]warning:[/] skipped {e}", highlight=False, soft_wrap=True)
        doc = result.to_dict()
        cad = CADModel(r, like=structure)
        baseline = None
        if method != "ols" and val:
            try:  # unconstrained least squares on the same data, for the comparison table
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # the baseline's own identifiability is not reported
                    baseline = _identify(structure, fleet.equations if fleet is not None else train, method="ols",
                                         outliers="keep", weights=row_sigma)
            except SensorlessError:
                baseline = None
        doc["validation"] = {}
        for p, traj in zip(validate, val):
            m_id, m_cad = result.evaluate(traj), cad.score(traj)
            cols = {"CAD": m_cad}
            doc["validation"][str(p)] = {method: m_id.to_dict(), "cad": m_cad.to_dict()}
            if baseline is not None:
                cols["OLS"] = baseline.evaluate(traj)
                doc["validation"][str(p)]["ols"] = cols["OLS"].to_dict()
            cols[method.upper()] = m_id
            console.print(metrics_table(f"held-out {Path(p).name}", cols))
        _print_bodies(result)
        shown = val[0] if val else (train[0] if train else None)
        if plot and shown is not None:  # with --scheduler, the client may not see the training files
            _plot_window(shown, structure, {method.upper(): result, "CAD": cad}, tmp / "torques.png",
                         f"{r.name}: {'held-out' if val else 'training'} torques")
        _floating_base_checks(structure, result, doc, train, val, validate)
        if _plain(structure) and train and any(t in structure.joint_terms for t in ("fv", "fc", "stribeck")):
            from ..report.friction_plot import plot_friction

            plot_friction(structure, result.parameters, train, tmp / "friction.png",
                          title=f"{r.name}: joint friction (training logs)")
        _export(result, tmp, doc)
        from ..identification.result import write_json_atomic

        write_json_atomic(doc, tmp / "result.json")
        from ..report.html import write_html_report

        write_html_report(tmp, doc)
    d = result.diagnostics
    extra = (f"γ = {d['gamma']:.3g}, solver {d['lmi']['solver']} ({d['lmi']['status']}), "
             f"all bodies consistent: {d['lmi']['consistent']}" if method == "lmi"
             else f"condition number {d['condition_number']:.1f}")
    skip_note = f", {len(skipped)} file(s) skipped (listed in result.json)" if skipped else ""
    console.print(f"{len(result.base.independent)} base parameters, {extra}{skip_note}; wrote {out}/")


PLOT_WINDOW = 20_000  # samples of the log shown in torques.png (from its start)
PLOT_POINTS = 2_000  # points per curve after decimation


def _plot_window(traj, structure, models: dict, path: Path, title: str) -> None:
    """torques.png: measured vs predicted effort on the first ``PLOT_WINDOW`` samples, every k-th sample
    (≤ ``PLOT_POINTS`` points). Only those samples are predicted (the model is pointwise in q, v, v̇)."""
    from ..report import plot_torques

    n = min(len(traj), PLOT_WINDOW)
    part = traj.take(np.arange(0, n, max(1, math.ceil(n / PLOT_POINTS))))
    span = f"first {part.t[-1] - traj.t[0]:.3g} s" if n < len(traj) else "whole log"
    plot_torques(part.t, structure.target(part), {k: m.predict(part) for k, m in models.items()},
                 structure.row_names, path, title=f"{title} ({span}, {len(part)} points)")


def _load_training(data, r, prep: dict, skip_bad: bool):
    """Local path: every training log in memory; with --skip-bad a file that fails is left out and reported."""
    if not skip_bad:
        return load_logs(data, r, **prep), data, []
    from .common import load_log

    train, used, skipped = [], [], []
    for p in data:
        try:
            train.append(load_log(p, r, **prep))
            used.append(p)
        except SensorlessError as exc:
            skipped.append((str(p), str(exc) if str(p) in str(exc) else f"{p}: {exc}"))
    if not train:
        raise SensorlessError("every --data file was skipped: " + "; ".join(e for _, e in skipped))
    return train, used, skipped


def _first_training_log(data, r, prep: dict) -> list:
    """The first training log for the torque plot, if this machine can read it (else no plot)."""
    from .common import load_log

    try:
        return [load_log(data[0], r, **prep)]
    except SensorlessError:
        return []


def _print_bodies(result) -> None:
    """Identified mass per body, named by joint and link (result.json: parameter_links)."""
    from rich.table import Table

    from ..identification.result import body_links

    links = body_links(result.robot)
    t = Table(title="identified bodies (parameters 'joint.p' in result.json; 'link.p' in parameter_links)")
    for col in ("joint", "link", "m [kg]", "CAD m [kg]"):
        t.add_column(col, justify="right" if "m" in col else "left")
    pi, pi0 = result.inertial_parameters.reshape(-1, 10), result.robot.inertial_parameters().reshape(-1, 10)
    for k, b in enumerate(result.robot.body_names):
        t.add_row(b, links.get(b, b), f"{pi[k, 0]:.3f}", f"{pi0[k, 0]:.3f}")
    console.print(t)


def _plain(structure) -> bool:
    """A per-joint ModelStructure (no contact projection, no coupled drives)."""
    from ..regressor import ModelStructure

    return type(structure) is ModelStructure


def _friction_options(coulomb_smoothing: str, stribeck_velocity: str):
    """--coulomb-smoothing / --stribeck-velocity as 'auto' or a number (OptionError otherwise)."""
    out = []
    for flag, text in (("--coulomb-smoothing", coulomb_smoothing), ("--stribeck-velocity", stribeck_velocity)):
        if str(text).strip().lower() == "auto":
            out.append("auto")
            continue
        try:
            x = float(text)
        except ValueError:
            raise OptionError(f"{flag} must be a number or 'auto', got '{text}'") from None
        if not (math.isfinite(x) and x >= 0) or (flag == "--stribeck-velocity" and x == 0):
            raise OptionError(f"{flag} must be a finite number {'>' if 'stribeck' in flag else '>='} 0 or 'auto', got '{text}'")
        out.append(x)
    return tuple(out)


def _check_identify_options(method, gamma, regularization, coulomb_smoothing, outliers, weights="auto") -> None:
    """OptionError, naming the option, for values no run can use (checked before any work)."""
    from ..data.outliers import OUTLIER_MODES
    from ..identification import METHODS

    if method not in METHODS:
        raise OptionError(f"--method must be one of {', '.join(METHODS)}, got '{method}'")
    if gamma != "auto":
        try:
            g = float(gamma)
        except ValueError:
            raise OptionError(f"--gamma must be a number or 'auto', got '{gamma}'") from None
        if not (math.isfinite(g) and g >= 0):
            raise OptionError(f"--gamma must be a finite number >= 0 or 'auto', got '{gamma}'")
    if regularization not in ("none", "pullback"):  # the default is checked without loading cvxpy
        from ..identification.regularizers import REGULARIZERS
    if regularization not in ("none", "pullback") and regularization not in REGULARIZERS:
        raise OptionError(f"--regularization must be one of {', '.join(sorted(REGULARIZERS))}, none; "
                          f"got '{regularization}'")
    if coulomb_smoothing != "auto" and not (math.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0):
        raise OptionError(f"--coulomb-smoothing must be a finite number >= 0, got {coulomb_smoothing}")
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"--outliers must be one of {', '.join(OUTLIER_MODES)}, got '{outliers}'")
    if weights not in ("auto", "none") and not Path(weights).is_file():
        raise OptionError(f"--weights must be auto, none or a JSON/CSV file of per-joint σ; no file '{weights}'")


def _structure(robot, joint_terms: str, coulomb_smoothing: float, contact_frames, contact_dims, contact_offset,
               contact_mode, *, contact_rows: str = "auto", wrench_offset: str = "none", offset_axes: str = "xy",
               train=None):
    """ModelStructure, or ContactStructure when contact frames are given (wrench mode: rows
    chosen from the training logs' torques when ``contact_rows="auto"``, with a message)."""
    from ..errors import RobotModelError
    from ..regressor import ModelStructure

    terms = joint_terms if "=" in joint_terms else tuple(t.strip() for t in joint_terms.split(",") if t.strip())
    if not (math.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0):
        raise OptionError(f"--coulomb-smoothing must be a finite number >= 0, got {coulomb_smoothing}")
    if hasattr(robot, "make_structure"):  # coupled joints (dvrk_psm): drive terms of its own
        if contact_frames:
            raise SensorlessError(f"--contact-frames: '{robot.name}' is a fixed-base coupled-joint model")
        if isinstance(terms, str):
            raise OptionError(f"--joint-terms per joint ('JOINT=...') is not supported for '{robot.name}' (drive terms)")
        return robot.make_structure(terms, coulomb_smoothing)
    if not contact_frames:
        if contact_dims:
            raise SensorlessError("--contact-dims needs --contact-frames")
        if contact_rows != "auto" or wrench_offset != "none":
            raise SensorlessError("--contact-rows and --wrench-offset need --contact-frames and --contact-mode wrench")
        try:
            return ModelStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing)
        except RobotModelError as exc:
            raise OptionError(f"--joint-terms '{joint_terms}': {exc}") from None
    if isinstance(terms, str):
        raise OptionError("--joint-terms per joint ('JOINT=...') is not supported with --contact-frames")
    from ..regressor.contact import ContactStructure

    frames = tuple(f.strip() for f in contact_frames.split(",") if f.strip())
    try:
        dims = tuple(int(d) for d in contact_dims.split(",")) if contact_dims else ()
    except ValueError:
        raise SensorlessError(f"--contact-dims must be comma-separated 3 or 6, got '{contact_dims}'") from None
    if contact_mode == "wrench" and contact_rows == "auto" and train:
        from ..regressor.contact import choose_contact_rows

        contact_rows, why = choose_contact_rows(train)
        console.print(f"contact rows: {contact_rows} — {why}")
    return ContactStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing, contact_frames=frames,
                            contact_dims=dims, contact_offset=contact_offset, mode=contact_mode,
                            contact_rows=contact_rows, wrench_offset=wrench_offset, offset_axes=offset_axes)


def _imu_frame_logs(logs, robot, frame: str, savgol_window):
    """Recompute base_a with the accelerometer in model frame ``frame`` (needs 'imu_acc')."""
    from ..data import base_acceleration

    return [base_acceleration(t, window=savgol_window or 11, robot=robot, imu_frame=frame) for t in logs]


def _floating_base_checks(structure, result, doc: dict, train, val, validate) -> None:
    """Measured-wrench identification: bias values, world-axis base-wrench RMSE and the
    CoM-vs-CoP check on standing windows, per log, into ``doc["floating_base"]``."""
    from ..regressor.contact import ContactStructure

    if not isinstance(structure, ContactStructure) or structure.mode != "wrench":
        return
    from ..identification.floating_base import base_wrench_metrics, com_cop_check

    p = result.parameters
    fb = {"contact_rows": structure.settings()["contact_rows"], "wrench_offset": structure.offset_values(p),
          "train": [], "validation": {}}
    for traj in train:
        fb["train"].append({"base_wrench": base_wrench_metrics(structure, p, traj),
                            "com_cop": com_cop_check(structure, p, traj)})
    for path, traj in zip(validate, val):
        fb["validation"][str(path)] = {"base_wrench": base_wrench_metrics(structure, p, traj),
                                       "com_cop": com_cop_check(structure, p, traj)}
    doc["floating_base"] = fb
    mass = doc.get("mass_properties") or {}
    bw = fb["train"][0]["base_wrench"]
    cc = fb["train"][0]["com_cop"]
    console.print(
        f"identified total mass {mass.get('total_mass', float('nan')):.3f} kg (model file "
        f"{mass.get('urdf_total_mass', float('nan')):.3f} kg); base-wrench RMSE (world) {bw['force_rmse_norm']:.3g} N, "
        f"{bw['moment_rmse_norm']:.3g} N·m"
        + (f"; CoM–CoP on standing windows {1e3 * cc['distance_mean']:.1f} mm" if cc["n_samples"] else ""))
    for traj_doc in fb["train"]:
        if traj_doc["com_cop"]["ok"] is False:
            err_console.print(f"[yellow]warning:[/] the identified CoM is {1e3 * traj_doc['com_cop']['distance_mean']:.1f} mm "
                              "from the measured CoP on standing windows (a wrench bias? try --wrench-offset)")


def _lmi_kwargs(robot, structure, method, prior, regularization, gamma, ellipsoids, contain_prior) -> dict:
    """Options of `identify(method="lmi")` from the command line."""
    if method != "lmi":
        return {}
    from ..identification import auto_ellipsoids

    if gamma != "auto":
        try:
            gamma = float(gamma)
        except ValueError:
            raise SensorlessError(f"--gamma must be a number or 'auto', got '{gamma}'") from None
    prior_vec = None
    if prior is not None:
        from ..robot import load_robot

        p = load_robot(prior, floating_base=robot.floating_base)
        missing = [b for b in robot.body_names if b not in p.body_names]
        if missing:
            raise SensorlessError(f"{prior}: prior model lacks bodies {missing} of {robot.name}")
        prior_vec = structure.prior()
        pi = p.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(robot.body_names):
            prior_vec[10 * k : 10 * k + 10] = pi[p.body_names.index(b)]
    ell = {"auto": None, "kinematic": "kinematic", "none": False}.get(ellipsoids)
    if ellipsoids not in ("auto", "kinematic", "none"):
        raise SensorlessError(f"--ellipsoids must be auto, kinematic or none, got '{ellipsoids}'")
    if ell is not False and not contain_prior:
        ell = auto_ellipsoids(robot, geometry=None if ell == "kinematic" else "auto", contain_prior=False)
    reg = None if regularization == "none" else regularization
    return {"gamma": gamma, "regularization": reg, "prior": prior_vec, "ellipsoids": ell}


def _export(result, tmp: Path, doc: dict) -> None:
    """URDF + joint terms; a model that is not a physical body is reported, not exported."""
    from ..errors import SensorlessError as _E
    from ..export import write_joint_terms
    from ..parameters import JointTerms, check_physical_consistency

    reports = check_physical_consistency(result.inertial_parameters, list(result.robot.body_names))
    bad = [rep.name for rep in reports if not rep.consistent]
    doc["physical_consistency"] = {"inconsistent_bodies": bad, "n_bodies": len(reports)}
    if hasattr(result.structure, "drive_values"):  # coupled joints: drive terms, no URDF (result.json is the model)
        from ..identification.result import write_json_atomic

        write_json_atomic(result.structure.drive_values(result.parameters), tmp / "drive_terms.json")
        doc["urdf"] = None
        doc["urdf_error"] = f"'{result.robot.name}' has coupled joints; a URDF cannot hold it (result.json does)"
        return
    from ..parameters import TERM_NAMES

    terms = JointTerms.from_dict({j: {t: v for t, v in d.items() if t in TERM_NAMES} for j, d in result.joint_terms().items()})
    write_joint_terms(terms, tmp / "joint_terms.json")
    try:
        from ..urdf_patch import export_urdf  # the source URDF patched (meshes kept), else write_urdf

        _, doc["urdf_export"] = export_urdf(result.robot, result.inertial_parameters, tmp / "model.urdf", joint_terms=terms)
        doc["urdf"] = "model.urdf"
    except _E as exc:
        doc["urdf"] = None
        doc["urdf_error"] = str(exc)
        err_console.print(f"[yellow]warning:[/] no URDF written: {exc}")


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


@bench_app.command("identify")
@guarded
def bench_identify(
    robot: str = typer.Option("panda", help=ROBOT_HELP),
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts"),
    out: Path = typer.Option(Path("benchmarks/results/identify.json")),
) -> None:
    """Identification wall time, peak memory and per-sample cost vs a bare regressor call."""
    from ..benchmarks.identify import bench_identify as run

    res = run(robot, [int(float(s)) for s in samples.split(",")], console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    from ..identification.result import write_json_atomic

    write_json_atomic(res, out)
    console.print(f"wrote {out}")




@bench_app.command("dask")
@guarded
def bench_dask_cmd(
    robot: str = typer.Option("panda", help="example-robot-data name"),
    samples: str = typer.Option("1000000,10000000", help="comma-separated total sample counts"),
    samples_per_file: int = typer.Option(100_000, help="samples per generated Parquet file"),
    workers: int = typer.Option(2, help="LocalCluster worker processes (one thread each)"),
    method: str = typer.Option("ols", help="ols | wls"),
    out: Path = typer.Option(Path("benchmarks/results/dask.json")),
) -> None:
    """Dask LocalCluster vs single-process identification from generated Parquet logs (deleted afterwards)."""
    from ..benchmarks.fleet import bench_dask
    from ..identification.result import write_json_atomic

    sizes = tuple(int(float(s)) for s in samples.split(","))
    res = bench_dask(robot, sizes, samples_per_file=samples_per_file, workers=workers, method=method, console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")


@bench_app.command("contact")
@guarded
def bench_contact_cmd(
    samples: int = typer.Option(100_000, help="number of Solo12 stance/trot samples"),
    out: Path = typer.Option(Path("benchmarks/results/contact.json")),
) -> None:
    """Contact-projected identification: end-to-end time and projector cost vs a pinv loop."""
    from ..benchmarks.identify import bench_contact
    from ..identification.result import write_json_atomic

    res = bench_contact(samples, console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")


@bench_app.command("speed")
@guarded
def bench_speed_cmd(
    samples: int = typer.Option(100_000, help="samples of the in-memory compression log (UR5 and Panda)"),
    memory_sizes: str = typer.Option("100000,1000000", help="comma-separated sizes of the streamed peak-memory runs"),
    contact_samples: int = typer.Option(100_000, help="Solo12 samples for projector vs pinv loop"),
    identify_samples: int = typer.Option(100_000, help="samples of the UR5 log given to `sensorless identify`"),
    repeats: int = typer.Option(3, help="interleaved repetitions (best of)"),
    out: Path = typer.Option(Path("benchmarks/results/speed.json")),
) -> None:
    """Compression vs a bare regressor call, peak memory, contact projector vs pinv, CLI start-up and identify."""
    from ..benchmarks.speed import bench_speed
    from ..identification.result import write_json_atomic

    if min(samples, contact_samples, identify_samples, repeats) < 1:
        raise OptionError("--samples, --contact-samples, --identify-samples and --repeats must be >= 1")
    try:
        sizes = tuple(int(float(x)) for x in memory_sizes.split(","))
    except ValueError:
        raise OptionError(f"--memory-sizes must be comma-separated sample counts, got '{memory_sizes}'") from None
    res = bench_speed(n_compress=samples, memory_sizes=sizes, n_contact=contact_samples, n_identify=identify_samples,
                      repeats=repeats, console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")


@bench_app.command("lmi")
@guarded
def bench_lmi_cmd(
    robots: str = typer.Option("solo12,talos", help="comma-separated example-robot-data names"),
    solvers: str = typer.Option("CLARABEL,SCS", help="comma-separated cvxpy solver names"),
    out: Path = typer.Option(Path("benchmarks/results/lmi.json")),
) -> None:
    """Setup and solve time of the physically consistent (LMI) program from compressed data."""
    from ..benchmarks.lmi import bench_lmi
    from ..identification.result import write_json_atomic

    res = bench_lmi(robots=tuple(robots.split(",")), solvers=tuple(solvers.split(",")))
    for robot, r in res["results"].items():
        for solver, v in r["solvers"].items():
            console.print(
                f"{robot} ({r['n_bodies']} bodies, {r['n_params']} parameters) {solver}: setup {v.get('setup_seconds', float('nan')):.3f} s, "
                f"solve {v.get('solve_seconds', float('nan')):.3f} s, {v['status']}, consistent {v.get('consistent')}"
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")


@bench_app.command("peers")
@guarded
def bench_peers_cmd(
    recipe: Path = typer.Option(Path("benchmarks/peers.toml"), help="fixed recipe (TOML); the built-in copy when "
                                "the default file is absent"),
    seeds: Optional[str] = typer.Option(None, help="comma-separated seeds (default: the recipe's)"),
    cases: Optional[str] = typer.Option(None, help="comma-separated cases (default: all, main,hard)"),
    variants: str = typer.Option("lmi,ols,lmi_unweighted", help="fits: lmi (CLI defaults, --method lmi), ols "
                                 "(--method ols), lmi_unweighted (--method lmi --weights none), lmi_no_contain_prior"),
    out: Path = typer.Option(Path("benchmarks/results/peers.json")),
) -> None:
    """UR5 accuracy vs figaroh/rigeo's published figures: perturbed-truth inertials, random Fourier
    excitation, 1 % (main) and 5 %/600 samples (hard) noise; `identify` with its CLI defaults
    (--method lmi and ols). Held-out nRMSE vs the noise-free torque, mean and worst over seeds."""
    from ..benchmarks.peers import load_recipe, run_peers
    from ..identification.result import write_json_atomic

    default = recipe == Path("benchmarks/peers.toml") and not recipe.exists()
    rec = load_recipe(None if default else recipe)
    try:
        seed_list = tuple(int(s) for s in seeds.split(",")) if seeds else None
    except ValueError:
        raise OptionError(f"--seeds must be comma-separated integers, got '{seeds}'") from None
    res = run_peers(rec, seeds=seed_list, cases=tuple(cases.split(",")) if cases else None,
                    variants=tuple(v for v in variants.split(",") if v), console=console)
    res["recipe"]["file"] = "built-in (sensorless.benchmarks.peers.DEFAULT_RECIPE)" if default else str(recipe)
    for name, c in res["cases"].items():
        peers = ", ".join(f"{k} {v} %" for k, v in rec.peers.get(name, {}).items())
        for v in c:
            if isinstance(c[v], dict) and "mean_nrmse_percent" in c[v]:
                console.print(f"{name:4s} {v:15s} mean {c[v]['mean_nrmse_percent']:.3f} %, worst "
                              f"{c[v]['worst_nrmse_percent']:.3f} %, all bodies consistent: {c[v]['all_consistent']}")
        verdict = {True: "[green]PASS[/]", False: "[red]FAIL[/]", None: "—"}[c["passed"]]
        console.print(f"{name:4s} acceptance (lmi ≤ {c['acceptance_percent']} %, consistent): {verdict}; peers: {peers}")
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")

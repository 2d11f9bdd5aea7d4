"""`sensorless identify`: logs -> identified model (result.json, URDF, plots, report)."""

from __future__ import annotations

import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import ExcitationError, OptionError, SensorlessError
from .channel_options import base_velocity_option, pose_max_gap_option, wrench_frame_option
from .frames import frame_options
from .logs import log_trims, preprocessing_settings, trim_option
from .common import (
    LOG_FORMATS,
    robot_source_options,
    log_reading_options,
    MultiValueCommand,
    app,
    atomic_outdir,
    gains_option,
    guarded,
    load_logs,
    load_robot_arg,
    max_gap_option,
    path_inputs,
    resample_option,
    time_unit_option,
    velocity_option,
    force_option,
    lock_option,
    floating_base_option,
    robot_option,
    warn_line,
)
from .console import console
from .options import (
    RATE_HELP,
    TimeUnit,
    BaseVelocity,
    ContactMode,
    ContactRows,
    Ellipsoids,
    GammaSearch,
    Method,
    Outliers,
    Regularization,
    Rest,
    Velocity,
    WrenchOffset,
    check_config,
    config_option,
    resolved_options,
)
from .identify_model import _check_identify_options, _friction_options, _lmi_kwargs, _plain, _structure
from .identify_friction import _client_friction, _first_log_friction, _friction_logs, _friction_settings
from .identify_outputs import _figure_jobs, _floating_base_checks, _gamma_note, _plausible, _print_bodies
from .progress import progress_bars


@app.command(cls=MultiValueCommand)
@guarded
@robot_source_options
@log_reading_options(skip_bad=False)  # identify's own --skip-bad also skips bad files
@frame_options
def identify(
    config: Optional[Path] = config_option(),
    robot: str = robot_option(),
    data: List[Path] = typer.Option(..., help=f"training log(s): {LOG_FORMATS} (docs/logs.md); "
                                         "several after one flag (--data a.csv b.csv) or repeated"),
    validate: List[Path] = typer.Option([], help="held-out log(s) to report metrics on (several after one flag too)"),
    method: Method = typer.Option(Method.lmi, help="lmi: physically consistent, regularised toward the prior (the URDF); ols/wls: unconstrained least squares; svd: minimum-norm truncated SVD"),
    prior: Optional[Path] = typer.Option(None, help="lmi: URDF whose inertials are the prior (default: --robot's own)"),
    regularization: Regularization = typer.Option(Regularization.pullback, help="lmi: regulariser toward the prior"),
    gamma: str = typer.Option("auto", help="lmi: regularisation weight, or 'auto' (5-fold cross-validation)"),
    gamma_search: GammaSearch = typer.Option(GammaSearch.bracket, help="--gamma auto: bracket (golden-section search on "
                                             "the γ grid, the whole grid when its scores are not unimodal) | "
                                             "exhaustive (every γ of the grid) | closed-form (bracket; no conic "
                                             "solve where no constraint binds: exact, may pick another γ than "
                                             "the solver's scores)"),
    ellipsoids: Ellipsoids = typer.Option(Ellipsoids.auto, help="lmi: bounding ellipsoids"),
    contain_prior: bool = typer.Option(True, help="lmi: grow each ellipsoid to contain any body near the prior "
                                       "(second moments ×4, CoM within 7.5 cm); --no-contain-prior: geometry only"),
    weights: str = typer.Option("auto", help="per-joint noise weighting, every method: auto (two-step: σ from an "
                                "unweighted fit's residual) | none | FILE (JSON {joint: σ} or CSV 'joint,σ' rows)"),
    out: Path = typer.Option(..., help="output directory (written atomically)"),
    joint_terms: str = typer.Option("fv,fc,stribeck,offset,armature", help="joint terms fv,fc,stribeck,offset,armature (and opt-in presliding, docs/arm.md §7) for every "
                                    "joint, or per joint 'JOINT=fv,fc,offset;JOINT=fv;*=fv,fc' ('*': the joints not "
                                    "listed, else none); a --passive joint keeps its friction terms only "
                                    "(dvrk_psm: drive set 'authors' (default) or 'motors')"),
    columns: Optional[str] = typer.Option(None, help="column map, e.g. 'q=0:7;v=7:14;tau=14:21' or 'q=pos_{joint}'"),
    rate: Optional[float] = typer.Option(None, help=RATE_HELP),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off [Hz] before identification"),
    savgol_window: Optional[int] = typer.Option(None, help="Savitzky-Golay window: re-derive v̇ from the logged v "
                                                       "(v and v̇ from q when v is not logged)"),
    decimate: int = typer.Option(1, help="keep every n-th sample (after anti-alias filtering)"),
    gains: Optional[str] = gains_option(),
    trim: Optional[List[str]] = trim_option(),
    resample: str = resample_option(),
    velocity: Velocity = velocity_option(),
    max_gap: Optional[float] = max_gap_option(),
    time_unit: Optional[TimeUnit] = time_unit_option(),
    base_velocity: BaseVelocity = base_velocity_option(),
    pose_max_gap: Optional[float] = pose_max_gap_option(),
    lock: Optional[List[str]] = lock_option(),
    passive: Optional[List[str]] = typer.Option(
        None, help="joint without an actuator (repeatable; e.g. a leg's vertical rail): no torque is logged for it "
                   "(a 'tau' column may be absent or anything), its generalized force is 0 apart from its own friction "
                   "(fv, fc, stribeck terms only); its equation is fitted, and with --contact-frames it is projected "
                   "like a floating base's; kept in the model (settings.robot.passive)"),
    floating_base: Optional[bool] = floating_base_option(),
    contact_frames: Optional[str] = typer.Option(
        None, help="legged robots: comma-separated contact frames (feet); projects out the unknown contact "
                   "forces, flags from the log's 'contact' columns or detected from foot height/speed"),
    contact_dims: Optional[str] = typer.Option(None, help="per contact frame 3 (point foot) or 6 (flat foot); default 3"),
    contact_offset: float = typer.Option(0.0, help="radius [m] of spherical feet (contact point below the frame)"),
    contact_mode: ContactMode = typer.Option(ContactMode.projected, help="projected (no force sensing) | wrench (log has "
                                             "contact_forces)"),
    contact_rows: ContactRows = typer.Option(ContactRows.auto, help="wrench mode: base (6 floating-base rows; logs without joint "
                                     "torques) | all (+ torque rows) | auto (base when the logs have no torques)"),
    wrench_offset: WrenchOffset = typer.Option(WrenchOffset.none, help="wrench mode: constant wrench bias to identify: none | net | "
                                      "foot (world axes, per foot) | sole (force in each sole frame)"),
    offset_axes: str = typer.Option("xy", help="force axes of --wrench-offset (xyz adds the vertical one, "
                                    "confounded with m·g on standing data)"),
    wrench_frame: Optional[List[str]] = wrench_frame_option(),
    imu_frame: Optional[str] = typer.Option(None, help="model frame of the accelerometer ('imu_acc'): rotation and "
                                            "lever arm from the model, on any body (e.g. imu_link)"),
    coulomb_smoothing: str = typer.Option("auto", help="ε [rad/s] of the Coulomb term tanh(v/ε); 0 = sgn(v); auto: 3 × "
                                          "the joint's velocity noise, or a transition width fitted per joint where "
                                          "the data support it (BIC; docs/arm.md §7)"),
    rest: Rest = typer.Option(Rest.auto, help="auto: a joint whose logged |v| stays within 5 noise stds of 0 over the "
                             "derivative window is at rest, v = v̇ = 0 there (no friction chatter at rest; the model "
                             "remembers it), unless it drifts consistently (creeping: v = its drift) | off "
                             "(docs/arm.md §7)"),
    stribeck_velocity: str = typer.Option("auto", help="vs [rad/s] of the 'stribeck' term: a number, or auto (per joint, "
                                          "the best of a grid of candidates compressed in the same pass)"),
    force: bool = force_option(),
    outliers: Outliers = typer.Option(Outliers.error, help="gross outliers in a log (robust MAD test): error | drop (with a "
                                                    "warning) | keep"),
    scheduler: Optional[str] = typer.Option(
        None, help="compress on Dask: 'local' (a LocalCluster on this machine) or a scheduler address "
                   "tcp://HOST:PORT; workers read the --data files themselves (see docs/fleet.md)"),
    workers: Optional[int] = typer.Option(None, help="--scheduler local: worker processes (default: one per core); "
                                                     "an address: wait until this many workers are connected"),
    skip_bad: bool = typer.Option(False, help="skip unreadable/invalid --data files (listed in result.json) instead of failing "
                                  "(corrupt rows at a log's start or end: --skip-bad-rows)"),
    accept_implausible: bool = typer.Option(False, help="keep going when a torque channel looks constant, dead, swapped, sign-flipped or > 100× "
                                            "off the prior model's scale, or the identified model is implausible (a "
                                            "non-finite value, a body heavier than the whole prior robot, a CoM "
                                            "outside its body, a determined total mass > 50 % off the prior's); "
                                            "refused by default, naming the joint or quantity"),
    urdf_values: str = typer.Option("prior", help="model.urdf: prior (a body whose mass the data do not determine "
                                    "gets the prior's mass, the identified dynamics unchanged) | regularised (the "
                                    "regularised values of result.json)"),
    stream: Optional[bool] = typer.Option(None, "--stream/--no-stream", help="one long training log read and compressed "
                                          "chunk by chunk in one pass (bounded memory; docs/logs.md): default when "
                                          "it applies to a log of >= 50,000 samples; --stream: at any length; "
                                          "--no-stream: the whole log in memory"),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write torques.png (a decimated window of the first "
                              "held-out log, else of the first training log, with residuals; torques_<limb>.png per "
                              "limb for a robot with several) and friction.png"),
) -> None:
    """Identify a dynamic model from logs; write result.json, model.urdf, joint_terms.json, torques.png, report.html.

    --data accepts glob patterns, '**' recursive (quote them: --data 'logs/**/*.parquet')."""
    args = dict(locals())
    _cheap_exit()
    plotter = _start_plotter() if plot else None  # first: it imports matplotlib in parallel with this process's work
    try:
        _identify(plotter=plotter, **args)
    finally:
        if plotter is not None:
            plotter.close()


def _identify(*, plotter, config, robot, data, validate, method, prior, regularization, gamma, ellipsoids, contain_prior,
              weights, out, joint_terms, columns, rate, lowpass, savgol_window, decimate, gains, trim, resample,
              velocity, max_gap, time_unit, base_velocity, pose_max_gap, lock, passive, floating_base, contact_frames,
              contact_dims, contact_offset, contact_mode, contact_rows, wrench_offset, offset_axes, wrench_frame,
              imu_frame, coulomb_smoothing, rest, stribeck_velocity, force, outliers, scheduler, workers, skip_bad,
              accept_implausible, urdf_values, stream, gamma_search, plot) -> None:
    """The body of :func:`identify` (``plotter``: the process drawing the figures, or None)."""
    check_config()
    from ..identification.urdf_values import URDF_VALUES

    if urdf_values not in URDF_VALUES:
        raise OptionError(f"--urdf-values must be one of {', '.join(URDF_VALUES)}, got '{urdf_values}'")
    coulomb_smoothing, stribeck_velocity = _friction_options(coulomb_smoothing, stribeck_velocity)
    _check_identify_options(method, gamma, regularization, coulomb_smoothing, outliers, weights)
    from ..data.prepare import check_preprocessing

    check_preprocessing(rate, lowpass, savgol_window, decimate)
    if workers is not None and scheduler is None:
        raise OptionError("--workers needs --scheduler (local or tcp://HOST:PORT)")
    if scheduler is not None and "presliding" in joint_terms:
        raise OptionError("--joint-terms presliding needs the whole logs in order (its state depends on the history "
                          "of q): run without --scheduler")
    if floating_base is None and contact_frames and not passive:
        floating_base = True  # a legged robot's base floats; with --passive a passive joint is the unactuated "base"
    from ..torque_models import CADModel, PhysicalModel
    from ..report import metrics_table

    r = load_robot_arg(robot, lock, floating_base, passive)
    from ..data.wrench_frames import wrench_frame_map
    from ..regressor.distributed import LogReader, expand_paths

    if wrench_frame and contact_mode != "wrench":
        raise OptionError("--wrench-frame needs --contact-mode wrench (measured contact wrenches)")
    wrench_frames = wrench_frame_map(wrench_frame, [f.strip() for f in (contact_frames or "").split(",") if f.strip()], r)
    data = [Path(p) for p in expand_paths(data)]
    trims = log_trims(trim, data, validate)
    prep = dict(columns=columns, rate=rate, lowpass=lowpass, savgol_window=savgol_window, decimate=decimate,
                gains=gains, trim=trims, resample=resample, velocity=velocity, max_gap=max_gap, outliers=outliers,
                rest=rest, time_unit=time_unit, base_velocity=base_velocity, pose_max_gap=pose_max_gap,
                wrench_frames=wrench_frames)
    # the figure process is stopped first on an error: nothing it writes outlives the hidden folder's removal
    with atomic_outdir(out, force, inputs=path_inputs(robot, data, validate, prior, weights)) as tmp, \
            progress_bars() as bars, (plotter if plotter is not None else nullcontext()):
        skipped: list = []
        streamed = None
        reading = bars.step("reading logs", total=len(validate) + (len(data) if scheduler is None else 0))
        from ..identification.streamed import streamable

        chunked = streamable(stream, data, r, prep, scheduler=scheduler, skip_bad=skip_bad, imu_frame=imu_frame,
                             contact_frames=contact_frames, passive=passive, joint_terms=joint_terms)
        if scheduler is None:
            train, data, skipped = ([], data, []) if chunked else _load_training(data, r, prep, skip_bad, reading.advance)
        val = load_logs(validate, r, **prep, progress=reading.advance)
        if imu_frame:  # on a cluster the workers do it (LogReader.imu_frame)
            val = _imu_frame_logs(val, r, imu_frame, savgol_window)
            if scheduler is None:
                train = _imu_frame_logs(train, r, imu_frame, savgol_window)
        # on a cluster, wrench mode with --contact-rows auto: the first training log, read here, decides the rows
        rows_from = _first_training_log(data, r, prep, skip_bad) if (scheduler is not None and contact_mode == "wrench"
                                                           and contact_rows == "auto") else None
        structure = _structure(r, joint_terms, 0.0 if coulomb_smoothing == "auto" else coulomb_smoothing, contact_frames, contact_dims, contact_offset,
                               contact_mode, contact_rows=contact_rows, wrench_offset=wrench_offset,
                               offset_axes=offset_axes, train=train if scheduler is None else rows_from)
        lmi_kw = _lmi_kwargs(r, structure, method, prior, regularization, gamma, ellipsoids, contain_prior)
        if lmi_kw.get("gamma") == "auto":
            lmi_kw["gamma_search"] = str(gamma_search)
        from ..identification.weights import weights_option

        row_sigma = weights_option(weights, structure.row_names)
        fleet = None
        if scheduler is not None:
            from .fleet import identify_on_dask

            friction_fit, first = None, rows_from
            if _plain(structure) and (coulomb_smoothing == "auto" or "stribeck" in structure.joint_terms):
                first = _first_training_log(data, r, prep, skip_bad)
                structure, friction_fit = _client_friction(structure, first, data[0], r, prep, coulomb_smoothing,
                                                           stribeck_velocity, lowpass)
            from ..data.limits import current_options

            reader = LogReader(**prep, imu_frame=imu_frame, skip_bad_rows=current_options().get("skip_bad_rows"),
                               angle_unit=current_options().get("angle_unit"))
            result, fleet = identify_on_dask(structure, data, scheduler, workers, reader,
                                             method, skip_bad,
                                             {**lmi_kw, "weights": row_sigma},
                                             friction_fit.stribeck_grid if friction_fit is not None else None,
                                             friction_fit.width_grid if friction_fit is not None else None, bars)
            structure = result.structure  # with the chosen Stribeck terms and transition widths
            if friction_fit is not None:
                from ..identification.friction import record_search

                record_search(friction_fit, result)
                result.settings["friction"] = _friction_settings(friction_fit, friction_fit, data[0])
            reuse = first is not None and fleet.files and Path(fleet.files[0]) == Path(data[0])
            data, skipped = [Path(p) for p in fleet.files], fleet.skipped
            train = (first if reuse else _first_training_log(data, r, prep, True)) if not val else []
            if imu_frame:
                train = _imu_frame_logs(train, r, imu_frame, savgol_window)
        else:
            total = chunked.n_samples if chunked else sum(len(t) for t in train)
            friction = _plain(structure) and (coulomb_smoothing == "auto" or "stribeck" in structure.joint_terms)
            kw = dict(progress=bars.step("regressor (samples)", total=total).advance, outliers="keep", validated=True,
                      weights=row_sigma, check_torques=not accept_implausible,
                      gamma_progress=bars.callback("γ cross-validation (folds, solves)"), **lmi_kw)
            fric, law, streamed = None, None, None
            if chunked:  # one pass over the log (sensorless.identification.streamed), or None: read it whole
                from ..identification.streamed import identify_streamed

                streamed = identify_streamed(chunked, structure, method, friction, coulomb_smoothing,
                                             stribeck_velocity, rest, kw, min_samples=0 if stream else None)
                if streamed is None:
                    train, data, skipped = _load_training(data, r, prep, skip_bad, reading.advance)
            if streamed is not None:
                friction = False
                result, structure, train = streamed.result, streamed.structure, [streamed.head]
                model = PhysicalModel.from_parameters(structure, result.parameters)
                if streamed.fit is not None:
                    result.settings["friction"] = _friction_settings(streamed.fit, streamed.law, data[:1])
            if friction:  # ε and the Stribeck candidates from the first training log, as on a cluster,
                # or from every training log when the first leaves a joint still (each joint where it moves)
                logs, paths = _friction_logs(structure, train, data)
                _, law = _first_log_friction(structure, logs, paths, r, prep, coulomb_smoothing,
                                             stribeck_velocity, lowpass)
                fric = dict(coulomb_smoothing=law.coulomb_smoothing if coulomb_smoothing == "auto"
                            else coulomb_smoothing,
                            stribeck_velocity=law.stribeck_grid or stribeck_velocity,
                            width_grid=law.width_grid)
            if streamed is None:
                try:  # the logs were validated (outliers handled) on reading: identify does not check them again
                    model = PhysicalModel(structure=structure, method=method, friction=fric, **kw).fit(train)
                except ExcitationError as exc:
                    raise ExcitationError(f"{', '.join(map(str, data))}: {exc}") from None
                result, structure = model.result_, model.structure_
            if friction:
                result.settings["friction"] = _friction_settings(model.friction_fit_, law, paths)
        result.settings.update({"data": [str(p) for p in data], "validate": [str(p) for p in validate],
                                "lowpass_hz": lowpass, "savgol_window": savgol_window, "decimate": decimate,
                                "columns": columns, "rate": rate,
                                "preprocessing": preprocessing_settings(
                                    train + val, columns=columns, gains=gains, rate=rate, trim=trims,
                                    resample=resample, lowpass=lowpass, savgol_window=savgol_window,
                                    velocity=velocity, decimate=decimate, max_gap=max_gap, rest=rest,
                                    time_unit=time_unit, base_velocity=base_velocity, pose_max_gap=pose_max_gap,
                                    wrench_frames=wrench_frames, paths=[*data, *validate],
                                    log_paths=[*data[:len(train)], *validate]),
                                "signals": {str(p): t.provenance for p, t in zip([*data, *validate], [*train, *val])}
                                if scheduler is None else {str(p): t.provenance for p, t in zip(validate, val)}})
        result.settings["config"] = {"file": None if config is None else str(config), "options": resolved_options()}
        if scheduler is not None or skip_bad:
            result.settings.update({"scheduler": scheduler, "skipped_files": [{"file": f, "error": e} for f, e in skipped]})
        for f, e in skipped:
            warn_line(f"skipped {e}")
        if scheduler is not None:  # identified on the workers: the same model, for scoring and plots
            model = PhysicalModel.from_parameters(structure, result.parameters)
        cad = CADModel(r, like=structure).fit()
        baseline = None
        if method != "ols" and val:
            equations = fleet.equations if fleet is not None else result.equations
            try:  # unconstrained least squares on the compressed equations of the fit, for the comparison table
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # the baseline's own identifiability is not reported
                    if streamed is not None:  # a solve on the streamed pass's equations
                        ols = streamed.ols_baseline(row_sigma)
                        baseline = PhysicalModel.from_parameters(ols.structure, ols.parameters)
                    else:
                        baseline = PhysicalModel(structure=structure, method="ols", outliers="keep", weights=row_sigma,
                                                 check_torques=False).fit(equations)
            except SensorlessError:
                baseline = None
        shown = val[0] if val else (train[0] if train else None)
        jobs = []  # the figures, drawn by the plot process while result.json is written
        if plot:
            friction_plot = (_plain(structure) and train
                             and any(t in structure.joint_terms for t in ("fv", "fc", "stribeck")))
            shown_models = {method.upper(): model, **({"OLS": baseline} if baseline is not None else {}), "CAD": cad}
            jobs = _figure_jobs(shown, structure, shown_models, [streamed.subsample] if streamed is not None else train,
                                result.parameters, tmp,
                                # with --scheduler, the client may not see the training files
                                f"{r.name}: {'held-out' if val else 'training'} torques" if shown is not None else None,
                                f"{r.name}: joint friction (training logs)" if friction_plot else None)
        drawn_elsewhere = bool(jobs) and plotter is not None and plotter.submit(jobs)
        _plausible(result, lmi_kw, accept_implausible, urdf_values)
        doc = result.to_dict()
        bars.close()  # the tables follow
        doc["validation"] = {}
        for p, traj in zip(validate, val):
            m_id, m_cad = model.score(traj), cad.score(traj)
            cols = {"CAD": m_cad}
            doc["validation"][str(p)] = {method: m_id.to_dict(), "cad": m_cad.to_dict()}
            if baseline is not None:
                cols["OLS"] = baseline.score(traj)
                doc["validation"][str(p)]["ols"] = cols["OLS"].to_dict()
            cols[method.upper()] = m_id
            console.print(metrics_table(f"held-out {Path(p).name}", cols))
        _print_bodies(result)
        _floating_base_checks(structure, result, doc, train, val, validate)
        from ..identification.artifact import save_model_folder

        save_model_folder(tmp, result, doc, urdf_values=urdf_values)
        if jobs and not (drawn_elsewhere and plotter.wait()):  # the plot process failed: draw here
            from ..report.plot_process import draw_job

            for job in jobs:
                draw_job(*job)
        from ..report.html import write_html_report

        write_html_report(tmp, doc)
    d = result.diagnostics
    extra = (f"{_gamma_note(d)}, solver {d['lmi']['solver']} ({d['lmi']['status']}), "
             f"all bodies consistent: {d['lmi']['consistent']}" if method == "lmi"
             else f"condition number {d['condition_number']:.1f}")
    counts = (d.get("verdicts") or {}).get("counts")
    if counts:
        extra += f"; body masses: {counts['data']} from the data, {counts['prior']} prior, {counts['undetermined']} undetermined"
    skip_note = f", {len(skipped)} file(s) skipped (listed in result.json)" if skipped else ""
    console.print(f"{len(result.base.independent)} base parameters, {extra}{skip_note}; wrote {out}/")


def _cheap_exit() -> None:
    """At interpreter exit, move every object to the garbage collector's permanent generation
    (``gc.freeze``) first: the collections of the shutdown then skip the objects the run made
    (cvxpy's problems among them; measured 1.3–2.1 s from the exit handlers to the end of the
    process on a loaded machine, 0.14–0.30 s with it). Everything the command writes is closed
    before then; the OS frees the memory."""
    import atexit
    import gc

    if not getattr(_cheap_exit, "registered", False):
        atexit.register(gc.freeze)
        _cheap_exit.registered = True


def _start_plotter():
    """The process drawing identify's figures (:class:`~.figure_process.FigureProcess`), when a core is
    idle for it; else None (the command draws them)."""
    from . import figure_process

    return figure_process.FigureProcess() if figure_process.idle_core() else None


def _load_training(data, r, prep: dict, skip_bad: bool, progress=None):
    """Local path: every training log in memory; with --skip-bad a file that fails is left out and reported.
    ``progress(1)`` after each file."""
    if not skip_bad:
        return load_logs(data, r, **prep, progress=progress), data, []
    from ..data.limits import read_options

    with read_options(skip_bad=True):  # corrupt bag/MCAP chunks: the rest of the file is read, with a warning
        return _load_each(data, r, prep, progress)


def _load_each(data, r, prep: dict, progress=None):
    from ..data.prepare import load_log

    train, used, skipped = [], [], []
    for p in data:
        try:
            train.append(load_log(p, r, **prep))
            used.append(p)
        except SensorlessError as exc:
            skipped.append((str(p), str(exc) if str(p) in str(exc) else f"{p}: {exc}"))
        if progress is not None:
            progress(1)
    if not train:
        raise SensorlessError("every --data file was skipped: " + "; ".join(e for _, e in skipped))
    return train, used, skipped


def _first_training_log(data, r, prep: dict, skip_bad: bool = False) -> list:
    """The first training log (friction law, contact rows, torque plot), if this machine has it; a file
    here that fails raises its error, as the workers would (one line, as a single-process run), unless
    ``skip_bad`` (then it is left to the workers to skip)."""
    import os

    from ..data.prepare import load_log

    if not os.path.isfile(str(data[0])):
        return []
    try:
        return [load_log(data[0], r, **prep)]
    except SensorlessError:
        if skip_bad:
            return []
        raise


def _imu_frame_logs(logs, robot, frame: str, savgol_window):
    """Recompute base_a with the accelerometer in model frame ``frame`` (needs 'imu_acc')."""
    from ..data.prepare import with_imu_frame

    return [with_imu_frame(t, robot, frame, savgol_window) for t in logs]

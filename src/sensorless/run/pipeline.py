"""One identification run, start to finish: :func:`identify_run` takes a :class:`~.config.RunConfig`
and returns a :class:`Run` whose :meth:`Run.save` writes the model folder (through
:func:`sensorless.identification.artifact.save_model_folder`, the one writer of result.json).

checks → robot → logs → structure → friction law and fit on the backend (:mod:`.backend`: local,
streamed or Dask) → settings → OLS baseline on the compressed equations → plausibility → held-out
scores → the result.json document (and the figures, as jobs). ``sensorless identify`` is this
function with the options of the command line."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..errors import DataWarning, setting
from .backend import Job, backend_for
from .checks import check_run_config
from .config import RunConfig
from .logs import imu_frame_logs, load_logs, preprocessing_settings
from .model import is_plain, lmi_settings, load_run_robot, model_structure, parse_add_frame

__all__ = ["Run", "identify_run", "reading_options", "run_inputs", "jobs_in"]


class _Step:
    def advance(self, n: float = 1) -> None:
        pass

    def update(self, done: float, total: float | None = None, note: str | None = None) -> None:
        pass


class _NoBars:
    """Progress bars that draw nothing (a caller without a terminal)."""

    def step(self, description: str, total: float | None = None) -> _Step:
        return _Step()

    def callback(self, description: str) -> None:
        return None

    def close(self) -> None:
        pass


@dataclass
class Run:
    """A finished run: ``result`` (IdentificationResult), ``doc`` (result.json as :meth:`save` writes it),
    the fitted ``model``, the ``cad`` model and the OLS ``baseline`` (or None), the held-out ``tables``
    ([(title, {label: metrics})]), the ``figures`` (jobs, with ``execution.plot``), the training and
    held-out logs this process read, and the files skipped."""

    config: RunConfig
    robot: Any
    result: Any
    doc: dict
    model: Any
    cad: Any
    baseline: Any
    structure: Any
    train: list
    val: list
    tables: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    skipped: list = field(default_factory=list)

    def save(self, out: str | Path | None = None, *, force: bool | None = None, plotter=None) -> Path:
        """Write the model folder ``out`` (default ``execution.out``) atomically
        (:func:`sensorless.io.atomic_output_dir`; an existing one only with ``force``, default
        ``execution.force``; never over an input): :meth:`write` into a hidden folder, then renamed."""
        from ..io import atomic_output_dir

        out = self.config.execution.out if out is None else out
        if out is None:
            from ..errors import OptionError, setting

            raise OptionError(f"{setting('execution.out')}: no output folder given")
        force = self.config.execution.force if force is None else force
        with atomic_output_dir(Path(out), force, inputs=run_inputs(self.config)) as tmp:
            self.write(tmp, plotter=plotter)
        return Path(out)

    def write(self, directory: str | Path, *, plotter=None, submitted: bool = False) -> None:
        """Write result.json, model.urdf, joint_terms.json (through
        :func:`~sensorless.identification.artifact.save_model_folder`), the figures and report.html into the
        existing folder ``directory``. ``plotter``: an object whose ``submit(jobs)`` returns True when it
        draws the figures and ``wait()`` True when it did (``submitted``: it has them already, from the
        ``figures`` hook of :func:`identify_run`); else they are drawn here."""
        from ..identification.artifact import save_model_folder
        from ..report.html import write_html_report

        directory = Path(directory)
        jobs = jobs_in(directory, self.figures)
        drawn_elsewhere = bool(jobs) and plotter is not None and (submitted or plotter.submit(jobs))
        save_model_folder(directory, self.result, self.doc, urdf_values=self.config.solver.urdf_values)
        if jobs and not (drawn_elsewhere and plotter.wait()):  # the plot process failed: draw here
            from ..report.plot_process import draw_job

            for job in jobs:
                draw_job(*job)
        write_html_report(directory, self.doc)


def _friction_plot(structure, training_logs: bool) -> bool:
    """friction.png is drawn: a per-joint model with a friction term, with its training logs in hand
    (not on a cluster)."""
    return bool(is_plain(structure) and training_logs and any(t in structure.joint_terms
                                                              for t in ("fv", "fc", "stribeck")))


def jobs_in(directory: str | Path, jobs: list) -> list:
    """The figure ``jobs`` of a run drawn into ``directory``."""
    return [(kind, arrays, Path(directory) / Path(path).name) for kind, arrays, path in jobs]


def run_inputs(config: RunConfig) -> list[Path]:
    """The existing files and folders a run reads (robot, logs with their patterns expanded, prior,
    weights): an output folder never replaces them."""
    import os

    from ..errors import DataError
    from ..regressor.distributed import expand_paths

    try:
        data = expand_paths([Path(p) for p in config.logs.data])
    except DataError:  # a pattern that matches nothing is the run's error, not this one's
        data = list(config.logs.data)
    values = [config.model.robot, *data, *config.logs.validate, config.solver.prior, config.solver.weights]
    return [Path(str(x)) for x in values if x is not None and str(x) and os.path.exists(str(x))]


def reading_options(config: RunConfig):
    """The context in which the run's logs are read (:func:`sensorless.data.limits.read_options`)."""
    from ..data.limits import read_options

    lg = config.logs
    return read_options(max_memory=lg.max_log_memory, allow_external=lg.allow_hdf5_external,
                        accept_implausible_gains=lg.accept_implausible_gains, skip_bad_rows=lg.skip_bad_rows,
                        angle_unit=None if lg.angle_unit is None else str(lg.angle_unit), joint_order=lg.joint_order,
                        time_from=lg.time_from, base_rpy=lg.base_rpy or None)


def identify_run(config: RunConfig, *, bars=None, say: Callable[[str], None] | None = None,
                 figures: Callable[[list], None] | None = None,
                 figure_layouts: Callable[[list], None] | None = None) -> Run:
    """Run the identification ``config`` describes (module docstring); nothing is written until
    :meth:`Run.save`. ``bars``: progress bars (``step(name, total)`` with ``advance``/``update``,
    ``callback(name)``, ``close()``; none drawn by default); ``say``: a callable for the lines the run
    reports (contact rows chosen, Dask cluster); warnings are :mod:`warnings`. ``figures(jobs)``: called
    with the figure jobs as soon as they are computed (a process may start drawing them while the run
    checks and scores the model); ``figure_layouts(layouts)``: called before the fit with what those
    figures will look like (:func:`~.figures.figure_layouts`), so that process can build them meanwhile."""
    with reading_options(config):
        return _identify(config, bars if bars is not None else _NoBars(), say, figures, figure_layouts)


def _robot(config: RunConfig):
    m = config.model
    floating = m.floating_base
    if floating is None and m.contact_frames and not m.passive:
        floating = True  # a legged robot's base floats; with passive joints a passive joint is the unactuated "base"
    return load_run_robot(m.robot, m.lock, floating, m.passive, frames=[parse_add_frame(s) for s in m.add_frame],
                          trust_xacro=m.trust_xacro, package_paths=m.package_path)


def _identify(config: RunConfig, bars, say, figures, layouts=None) -> Run:
    from ..data.trims import LogTrims
    from ..data.wrench_frames import wrench_frame_map
    from ..errors import setting
    from ..torque_models import CADModel
    from ..identification.weights import weights_option
    from ..data.integrity import duplicate_logs, unique_logs
    from ..regressor.distributed import expand_paths
    from .figures import figure_jobs, figure_layouts
    from .validation import blocked_scores, check_plausible, floating_base_report, held_out_scores, ols_baseline

    eps, vs = check_run_config(config)
    lg, m, sv, ex = config.logs, config.model, config.solver, config.execution
    r = _robot(config)
    contact_frames = [f.strip() for f in (m.contact_frames or "").split(",") if f.strip()]
    wrench_frames = wrench_frame_map(list(lg.wrench_frame) or None, contact_frames, r)
    data = unique_logs([Path(p) for p in expand_paths([Path(p) for p in lg.data])], setting("logs.data"))
    validate = unique_logs([Path(p) for p in lg.validate], setting("logs.validate"))
    for i, j, how in duplicate_logs([*data, *validate]):
        if i >= len(data) > j:  # a held-out log that is a training log scores the fit on its own samples
            warnings.warn(f"{setting('logs.validate')} {validate[i - len(data)]} is {how} {data[j]} of "
                          f"{setting('logs.data')}: its held-out scores are not held out", DataWarning, stacklevel=2)
    trims = LogTrims.parse(list(lg.trim) or None, setting("logs.trim"))
    trims.check([*data, *validate], setting("logs.trim"))
    prep = dict(columns=lg.columns, rate=lg.rate, lowpass=lg.lowpass, savgol_window=lg.savgol_window,
                decimate=lg.decimate, gains=lg.gains, trim=trims, resample=lg.resample, velocity=lg.velocity,
                max_gap=lg.max_gap, outliers=lg.outliers, rest=lg.rest, time_unit=lg.time_unit,
                base_velocity=lg.base_velocity, pose_max_gap=lg.pose_max_gap, wrench_frames=wrench_frames)
    backend = backend_for(Job(config, r, prep, eps, vs, bars, say))
    local = ex.scheduler is None
    reading = bars.step("reading logs", total=len(validate) + (len(data) if local else 0))
    train, data, skipped = backend.read(data, reading.advance)
    val = load_logs(validate, r, **prep, progress=reading.advance)
    if lg.imu_frame:  # on a cluster the workers do it (LogReader.imu_frame)
        val = imu_frame_logs(val, r, lg.imu_frame, lg.savgol_window)
    structure = model_structure(r, m.joint_terms, 0.0 if eps == "auto" else eps, m.contact_frames, m.contact_dims,
                                m.contact_offset, m.contact_mode, contact_rows=m.contact_rows,
                                wrench_offset=m.wrench_offset, offset_axes=m.offset_axes,
                                train=backend.contact_logs(data, train), say=say)
    lmi_kw = lmi_settings(r, structure, sv.method, sv.prior, sv.regularization, sv.gamma, sv.ellipsoids,
                          sv.contain_prior, load_prior=lambda p, floating_base: load_run_robot(
                              p, floating_base=floating_base, trust_xacro=m.trust_xacro, package_paths=m.package_path))
    if lmi_kw.get("gamma") == "auto":
        lmi_kw["gamma_search"] = str(sv.gamma_search)
    row_sigma = weights_option(sv.weights, structure.row_names)
    if ex.plot and layouts is not None and (local or val):  # (on a cluster without --validate: no figure)
        layouts(figure_layouts(structure, True, _friction_plot(structure, local), Path(".")))
    fit = backend.fit(structure, train, data, skipped, val, lmi_kw, row_sigma, reading.advance)
    result, structure, model, train, data, skipped = fit.result, fit.structure, fit.model, fit.train, fit.data, fit.skipped
    result.settings.update({"data": [str(p) for p in data], "validate": [str(p) for p in validate],
                            "lowpass_hz": lg.lowpass, "savgol_window": lg.savgol_window, "decimate": lg.decimate,
                            "columns": lg.columns, "rate": lg.rate,
                            "preprocessing": preprocessing_settings(
                                train + val, columns=lg.columns, gains=lg.gains, rate=lg.rate, trim=trims,
                                resample=lg.resample, lowpass=lg.lowpass, savgol_window=lg.savgol_window,
                                velocity=lg.velocity, decimate=lg.decimate, max_gap=lg.max_gap, rest=lg.rest,
                                time_unit=lg.time_unit, base_velocity=lg.base_velocity, pose_max_gap=lg.pose_max_gap,
                                wrench_frames=wrench_frames, paths=[*data, *validate],
                                log_paths=[*data[:len(train)], *validate]),
                            "signals": {str(p): t.provenance for p, t in zip([*data, *validate], [*train, *val])}
                            if local else {str(p): t.provenance for p, t in zip(validate, val)}})
    result.settings["config"] = {"file": config.source, "options": config.options()}
    if not local or lg.skip_bad:
        result.settings.update({"scheduler": ex.scheduler, "skipped_files": [{"file": f, "error": e} for f, e in skipped]})
    for f, e in skipped:
        warnings.warn(f"skipped {e}", stacklevel=2)
    cad = CADModel(r, like=structure).fit()
    baseline = ols_baseline(fit, row_sigma) if sv.method != "ols" and val else None
    shown = val[0] if val else (train[0] if train else None)
    jobs = []  # the figures, drawn by a plot process while result.json is written
    if ex.plot:
        friction_plot = _friction_plot(structure, bool(train))
        shown_models = {sv.method.upper(): model, **({"OLS": baseline} if baseline is not None else {}), "CAD": cad}
        jobs = figure_jobs(shown, structure, shown_models, [fit.streamed.subsample] if fit.streamed is not None else train,
                           result.parameters, Path("."),
                           # on a cluster, the client may not see the training files
                           f"{r.name}: {'held-out' if val else 'training'} torques" if shown is not None else None,
                           f"{r.name}: joint friction (training logs)" if friction_plot else None)
    if jobs and figures is not None:
        figures(jobs)
    check_plausible(result, lmi_kw, sv.accept_implausible, sv.urdf_values)
    doc = result.to_dict()
    doc["validation"], tables = held_out_scores(validate, val, str(sv.method), model, cad, baseline)
    if not val and train and fit.streamed is None:  # no held-out log: the blocked error of the training logs
        blocked = blocked_scores(result, train, lmi_kw, str(sv.method))
        if blocked is not None:
            doc["blocked_held_out"], table = blocked
            tables.append(table)
    fb = floating_base_report(structure, result, train, val, validate)
    if fb is not None:
        doc["floating_base"] = fb
    bars.close()
    return Run(config, r, result, doc, model, cad, baseline, structure, train, val, tables, jobs, skipped)

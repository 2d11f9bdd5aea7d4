"""Where a run's equations are compressed and solved, behind one interface: :class:`LocalBackend` (the
training logs in this process, or one long log streamed chunk by chunk, :mod:`~sensorless.identification.streamed`)
and :class:`DaskBackend` (the workers read and compress the files, the client solves; docs/fleet.md).
Each reads what it needs of the training logs (:meth:`read`) and fits the model (:meth:`fit`) with the
friction law measured where the backend sees the logs (:mod:`.friction`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..errors import ExcitationError
from .friction import client_friction, friction_logs, friction_settings, measure_friction, needs_friction_law
from .logs import first_training_log, imu_frame_logs, load_training

__all__ = ["Job", "Fit", "LocalBackend", "DaskBackend", "backend_for"]


@dataclass
class Job:
    """What a backend needs of a run: its config, robot, the reading options ``prep``, the friction law's
    ``eps`` / ``vs`` ('auto' or numbers), progress ``bars`` (``step(name, total)``, ``callback(name)``)
    and ``say`` (a line for the user)."""

    config: Any
    robot: Any
    prep: dict
    eps: Any
    vs: Any
    bars: Any
    say: Callable[[str], None] | None = None


@dataclass
class Fit:
    """A backend's answer: the result and its structure, the fitted model, the training logs this process
    holds (for figures and settings), the paths used and skipped, and the equations of the OLS baseline
    (``streamed``: the streamed pass, which solves its own)."""

    result: Any
    structure: Any
    model: Any
    train: list
    data: list
    skipped: list = field(default_factory=list)
    equations: Any = None
    streamed: Any = None


class LocalBackend:
    """Compress in this process: the training logs read whole, or one long log streamed."""

    def __init__(self, job: Job) -> None:
        self.job, self.chunked = job, None

    def read(self, data: list, progress=None) -> tuple[list, list, list]:
        """(training logs, paths used, skipped) before the held-out logs are read; none for a streamed log."""
        from ..identification.streamed import streamable

        c, j = self.job.config, self.job
        self.chunked = streamable(c.execution.stream, data, j.robot, j.prep, scheduler=None, skip_bad=c.logs.skip_bad,
                                  imu_frame=c.logs.imu_frame, contact_frames=c.model.contact_frames,
                                  passive=list(c.model.passive) or None, joint_terms=c.model.joint_terms)
        if self.chunked:
            return [], data, []
        train, data, skipped = load_training(data, j.robot, j.prep, c.logs.skip_bad, progress)
        if c.logs.imu_frame:
            train = imu_frame_logs(train, j.robot, c.logs.imu_frame, c.logs.savgol_window)
        return train, data, skipped

    def contact_logs(self, data: list, train: list) -> list:
        """The logs that choose wrench-mode contact rows."""
        return train

    def fit(self, structure, train: list, data: list, skipped: list, val: list, lmi_kw: dict, row_sigma,
            progress=None) -> Fit:
        from ..torque_models import PhysicalModel

        c, j = self.job.config, self.job
        method, eps, vs = c.solver.method, j.eps, j.vs
        total = self.chunked.n_samples if self.chunked else sum(len(t) for t in train)
        friction = needs_friction_law(structure, eps)
        kw = dict(progress=j.bars.step("regressor (samples)", total=total).advance, outliers="keep", validated=True,
                  weights=row_sigma, check_torques=not c.solver.accept_implausible_torques,
                  gamma_progress=j.bars.callback("γ cross-validation (folds, solves)"), **lmi_kw)
        fric, law, streamed = None, None, None
        if self.chunked:  # one pass over the log (sensorless.identification.streamed), or None: read it whole
            from ..identification.streamed import identify_streamed

            streamed = identify_streamed(self.chunked, structure, method, friction, eps, vs, c.logs.rest, kw,
                                         min_samples=0 if c.execution.stream else None)
            if streamed is None:
                train, data, skipped = load_training(data, j.robot, j.prep, c.logs.skip_bad, progress)
        if streamed is not None:
            friction = False
            result, structure, train = streamed.result, streamed.structure, [streamed.head]
            model = PhysicalModel.from_parameters(structure, result.parameters)
            if streamed.fit is not None:
                result.settings["friction"] = friction_settings(streamed.fit, streamed.law, data[:1])
        if friction:  # ε and the Stribeck candidates from the first training log, as on a cluster,
            # or from every training log when the first leaves a joint still (each joint where it moves)
            logs, paths = friction_logs(structure, train, data)
            _, law = measure_friction(structure, logs, paths, j.robot, j.prep, eps, vs, c.logs.lowpass)
            fric = dict(coulomb_smoothing=law.coulomb_smoothing if eps == "auto" else eps,
                        stribeck_velocity=law.stribeck_grid or vs, width_grid=law.width_grid)
        if streamed is None:
            try:  # the logs were validated (outliers handled) on reading: identify does not check them again
                model = PhysicalModel(structure=structure, method=method, friction=fric, **kw).fit(train)
            except ExcitationError as exc:
                raise ExcitationError(f"{', '.join(map(str, data))}: {exc}") from None
            result, structure = model.result_, model.structure_
        if friction:
            result.settings["friction"] = friction_settings(model.friction_fit_, law, paths)
        return Fit(result, structure, model, train, data, skipped, result.equations, streamed)


class DaskBackend:
    """Compress on a Dask cluster's workers (each reads its files), solve on this machine."""

    def __init__(self, job: Job) -> None:
        self.job, self.rows_from = job, None

    def read(self, data: list, progress=None) -> tuple[list, list, list]:
        return [], data, []

    def contact_logs(self, data: list, train: list) -> list | None:
        """Wrench mode with contact_rows auto: the first training log, read here, decides the rows."""
        c, j = self.job.config, self.job
        if c.model.contact_mode == "wrench" and c.model.contact_rows == "auto":
            self.rows_from = first_training_log(data, j.robot, j.prep, c.logs.skip_bad)
        return self.rows_from

    def fit(self, structure, train: list, data: list, skipped: list, val: list, lmi_kw: dict, row_sigma,
            progress=None) -> Fit:
        from ..data.limits import current_options
        from ..torque_models import PhysicalModel
        from ..regressor.distributed import LogReader

        c, j = self.job.config, self.job
        friction_fit, first = None, self.rows_from
        if needs_friction_law(structure, j.eps):
            first = first_training_log(data, j.robot, j.prep, c.logs.skip_bad)
            structure, friction_fit = client_friction(structure, first, data[0], j.robot, j.prep, j.eps, j.vs,
                                                      c.logs.lowpass, j.say)
        reader = LogReader(**j.prep, imu_frame=c.logs.imu_frame, skip_bad_rows=current_options().get("skip_bad_rows"),
                           angle_unit=current_options().get("angle_unit"))
        result, fleet = self._solve(structure, data, reader, {**lmi_kw, "weights": row_sigma},
                                    friction_fit.stribeck_grid if friction_fit is not None else None,
                                    friction_fit.width_grid if friction_fit is not None else None)
        structure = result.structure  # with the chosen Stribeck terms and transition widths
        if friction_fit is not None:
            from ..identification.friction import record_search

            record_search(friction_fit, result)
            result.settings["friction"] = friction_settings(friction_fit, friction_fit, data[0])
        reuse = first is not None and fleet.files and Path(fleet.files[0]) == Path(data[0])
        data, skipped = [Path(p) for p in fleet.files], fleet.skipped
        train = (first if reuse else first_training_log(data, j.robot, j.prep, True)) if not val else []
        if c.logs.imu_frame:
            train = imu_frame_logs(train, j.robot, c.logs.imu_frame, c.logs.savgol_window)
        model = PhysicalModel.from_parameters(structure, result.parameters)  # for scoring and plots
        return Fit(result, structure, model, train, data, skipped, fleet.equations)

    def _solve(self, structure, files, reader, lmi_kw: dict, stribeck_grid=None, width_grid=None):
        """Connect to (or start) the cluster, compress ``files`` on its workers (a bar of finished file
        tasks), solve here with the Stribeck / width candidates chosen on the client. (result, FleetEquations)."""
        from ..identification.fleet import identify_fleet
        from ..identification.stribeck import StribeckCandidates
        from ..regressor.dask_cluster import connect
        from ..regressor.distributed import compress_files

        c, bars = self.job.config, self.job.bars
        method, scheduler = c.solver.method, c.execution.scheduler
        lmi_auto = method == "lmi" and lmi_kw.get("gamma") == "auto"
        with connect(scheduler, c.execution.workers) as client:
            n = len(client.scheduler_info().get("workers", {}))
            if self.job.say is not None:
                self.job.say(f"Dask: {scheduler} ({n} workers), {len(files)} files")
            step = bars.step("files (dask)", total=len(files) * (2 if lmi_auto else 1))
            cand = StribeckCandidates(structure, stribeck_grid, width_grid) if (stribeck_grid or width_grid) else None
            fleet = compress_files(cand or structure, files, client=client, reader=reader, skip_bad=c.logs.skip_bad,
                                   n_folds=5 if lmi_auto else None, progress=step.advance)
        try:
            cv = bars.callback("γ cross-validation (solves)")
            result = identify_fleet(structure, fleet, method=method, stribeck_grid=stribeck_grid,
                                    width_grid=width_grid, **({"gamma_progress": cv} if lmi_auto else {}), **lmi_kw)
            return result, fleet
        except ExcitationError as exc:
            raise ExcitationError(f"{len(fleet.files)} files ({fleet.files[0]} …): {exc}") from None


def backend_for(job: Job) -> "LocalBackend | DaskBackend":
    """The run's backend: Dask with ``execution.scheduler``, else local."""
    return LocalBackend(job) if job.config.execution.scheduler is None else DaskBackend(job)

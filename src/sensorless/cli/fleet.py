"""`identify --scheduler`: the Dask path of the identify command (see docs/fleet.md)."""

from __future__ import annotations

from ..errors import ExcitationError
from .console import err_console


def identify_on_dask(structure, files, scheduler: str, workers, reader, method: str, skip_bad: bool, lmi_kw: dict,
                     stribeck_grid=None, width_grid=None, bars=None):
    """Connect to (or start) a Dask cluster, compress ``files`` on its workers with a progress
    bar of finished file tasks (a step of ``bars``, :func:`~.progress.progress_bars`), solve on this machine. ``stribeck_grid`` / ``width_grid``: Stribeck
    velocity and transition width candidates compressed with the model and chosen on the client
    (:mod:`~sensorless.identification.stribeck`).
    Returns (result, FleetEquations)."""
    from ..identification.stribeck import StribeckCandidates

    from ..identification.fleet import identify_fleet
    from ..regressor.dask_cluster import connect
    from ..regressor.distributed import compress_files

    lmi_auto = method == "lmi" and lmi_kw.get("gamma") == "auto"
    with connect(scheduler, workers) as client:
        n = len(client.scheduler_info().get("workers", {}))
        err_console.print(f"Dask: {scheduler} ({n} workers), {len(files)} files", highlight=False)
        step = bars.step("files (dask)", total=len(files) * (2 if lmi_auto else 1)) if bars is not None else None
        cand = StribeckCandidates(structure, stribeck_grid, width_grid) if (stribeck_grid or width_grid) else None
        fleet = compress_files(cand or structure, files, client=client, reader=reader, skip_bad=skip_bad,
                               n_folds=5 if lmi_auto else None, progress=step.advance if step is not None else None)
    try:
        cv = bars.callback("γ cross-validation (solves)") if bars is not None else None
        result = identify_fleet(structure, fleet, method=method, stribeck_grid=stribeck_grid, width_grid=width_grid,
                                **({"gamma_progress": cv} if lmi_auto else {}), **lmi_kw)
        return result, fleet
    except ExcitationError as exc:
        raise ExcitationError(f"{len(fleet.files)} files ({fleet.files[0]} …): {exc}") from None

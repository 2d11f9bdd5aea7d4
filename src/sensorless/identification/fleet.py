"""identify_files(): identification from many log files, compressed on a Dask cluster.

The files are compressed by :func:`~sensorless.regressor.distributed.compress_files`
(one task per file, partial normal equations summed by a tree reduction) and the model is
solved on the client by :func:`~.identify.identify` from the summed equations, so OLS,
two-step WLS (σ_r from the per-row OLS residual of the same equations), SVD and LMI with a
fixed γ are the local computations on the same sums. LMI with ``gamma="auto"`` gets its
cross-validation folds from the workers too (the same contiguous/phase blocks as
:func:`~.gamma.cross_validate_gamma` cuts from trajectories).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence


from ..regressor.distributed import FleetEquations, compress_files
from ..regressor.terms import ModelStructure
from .identify import identify
from .result import IdentificationResult
from .stribeck import StribeckCandidates, carry_prior, choose_stribeck

__all__ = ["identify_files", "identify_fleet"]


def identify_files(
    structure: ModelStructure,
    files: Sequence[str | Path] | str | Path,
    *,
    client=None,
    reader: Callable | None = None,
    method: str = "ols",
    skip_bad: bool = False,
    retries: int = 2,
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
    **identify_kwargs: Any,
) -> IdentificationResult:
    """:func:`~.identify.identify` on log files read by the workers of ``client``.

    ``files``: paths or glob patterns. ``reader``, ``skip_bad``, ``retries``, ``progress`` as
    :func:`~sensorless.regressor.distributed.compress_files`; the other keywords go to
    ``identify``. ``result.settings`` lists the files used and every skipped file with its error.
    """
    lmi_auto = method == "lmi" and identify_kwargs.get("gamma", 1e-3) == "auto"
    grid, widths = identify_kwargs.get("stribeck_grid"), identify_kwargs.get("width_grid")
    fleet = compress_files(StribeckCandidates(structure, grid, widths) if (grid or widths) else structure, files, client=client, reader=reader, chunk=chunk, skip_bad=skip_bad,
                           retries=retries, n_folds=5 if lmi_auto else None, progress=progress)
    return identify_fleet(structure, fleet, method=method, chunk=chunk, **identify_kwargs)


def identify_fleet(structure: ModelStructure, fleet: FleetEquations, *, method: str = "ols",
                   stribeck_grid: Mapping[str, Sequence[float]] | None = None,
                   width_grid: Mapping[str, Sequence[float]] | None = None,
                   **identify_kwargs: Any) -> IdentificationResult:
    """Solve from already summed :class:`FleetEquations` (see :func:`identify_files`); with
    ``stribeck_grid`` / ``width_grid`` they are the equations of :class:`~.stribeck.StribeckCandidates`
    on those grids, and vs and the widths are chosen on them as :func:`~.identify.identify` does."""
    kw = dict(identify_kwargs)
    cv, record = None, None
    if stribeck_grid or width_grid:
        from .weights import check_weights

        cand = StribeckCandidates(structure, stribeck_grid, width_grid)
        choice, record = choose_stribeck(cand, fleet.equations, check_weights(kw.get("weights", "auto"),
                                                                              structure.row_names))
        before, structure = structure, cand.structure_for(choice)
        if kw.get("prior") is not None:  # the search may have dropped Stribeck terms
            kw["prior"] = carry_prior(kw["prior"], before, structure)
        fleet = dataclasses.replace(fleet, equations=cand.select(fleet.equations, choice),
                                    folds=[cand.select(f, choice) for f in fleet.folds] if fleet.folds else fleet.folds)
    if method == "lmi" and kw.get("gamma", 1e-3) == "auto":
        from .least_squares import row_weights
        from .gamma import cross_validate_gamma
        from .weights import check_weights

        row_w = row_weights(fleet.equations, check_weights(kw.get("weights", "auto"), structure.row_names))
        cv = cross_validate_gamma(structure, fleet.folds, prior=kw.get("prior"),
                                  regularization=kw.get("regularization", "pullback"),
                                  ellipsoids=kw.get("ellipsoids"), row_weights=row_w,
                                  progress=kw.get("gamma_progress"), search=kw.get("gamma_search", "bracket"),
                                  workers=kw.get("gamma_workers"), **dict(kw.get("lmi_options") or {}))
        kw["gamma"] = cv.gamma
    result = identify(structure, fleet.equations, method=method, **kw)
    if cv is not None:
        result.diagnostics["gamma_selection"] = cv.to_dict()
        result.settings["gamma_search"] = kw.get("gamma_search", "bracket")
        if cv.edge is not None:  # (warned by cross_validate_gamma)
            result.diagnostics["warnings"].append(cv.edge_message())
    if record is not None:
        result.diagnostics["stribeck_search"] = record
    result.diagnostics["compress_seconds"] = fleet.seconds
    result.settings.update(fleet.summary())
    return result

"""The blocked held-out error of a fit from its own logs: how it predicts what it was not fitted on.

Without held-out logs (``identify`` without ``--validate``) the training error says little: a model
with many parameters follows the log's noise. :func:`blocked_held_out` cuts the training logs into
:data:`BLOCKS` contiguous time blocks (:func:`~sensorless.data.blocks.blocked_folds`), refits the
run's model on every block but one, on the same normal equations (one pass over the samples:
:func:`~.gamma.split_folds`), and predicts the block left out: per joint RMSE, NRMSE (of the
measured range) and relative RMS pooled over the blocks, as for a held-out log. The model's
structure (joint terms, friction law), γ and row weights are those chosen on the whole data, so
the figure is a little optimistic; it is labelled as the blocked error of the training logs, never
as a held-out log's.
"""

from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import SensorlessError
from .metrics import TorqueMetrics, metrics_from_sums, static_rows

__all__ = ["BLOCKS", "LABEL", "blocked_held_out"]

#: contiguous time blocks (the folds of the γ cross-validation)
BLOCKS = 5
#: how outputs name the figure
LABEL = (f"blocked held-out, training logs: {BLOCKS} contiguous time blocks, each predicted by the model "
         f"refit on the other {BLOCKS - 1} (no --validate log)")


def blocked_held_out(result, trajs: Sequence[Trajectory], fit_kwargs: dict, *, n_blocks: int = BLOCKS,
                     chunk: int = 2048) -> TorqueMetrics | None:
    """Pooled held-out metrics of ``result``'s model over ``n_blocks`` contiguous blocks of ``trajs``
    (module docstring); ``fit_kwargs``: :func:`~.identify.identify`'s settings of the run (prior,
    regularisation, ellipsoids). None when the logs are too short for the blocks or a refit fails."""
    from .gamma import split_folds
    from .identify import identify

    structure, d = result.structure, result.diagnostics
    total = sum(len(t) for t in trajs)
    if n_blocks < 2 or total < 4 * n_blocks:
        return None
    row_w = d.get("row_weights")
    kw = {k: v for k, v in fit_kwargs.items() if k in ("prior", "regularization", "ellipsoids")}
    if result.method == "lmi":
        kw["gamma"] = float(d.get("gamma", result.settings.get("gamma", 0.0)))
    weights = None if row_w is None else [1.0 / np.sqrt(row_w[r]) if row_w[r] > 0 else 1.0 for r in structure.row_names]
    try:
        folds = split_folds(structure, list(trajs), n_blocks, chunk, period=None)
        sse = np.zeros(len(structure.row_names))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the refits' own identifiability is the run's, already reported
            for f, held in enumerate(folds):
                rest = None
                for g, ne in enumerate(folds):
                    if g != f:
                        rest = ne if rest is None else rest.merge(ne)
                fit = identify(structure, rest, method=result.method, weights=weights, check_torques=False,
                               outliers="keep", validated=True, **kw)
                sse += held.residual_ss(fit.parameters)
    except (SensorlessError, np.linalg.LinAlgError, ValueError):
        return None
    ne = folds[0]
    for other in folds[1:]:
        ne = ne.merge(other)
    m = metrics_from_sums(structure.row_names, sse, ne.c, ne.y_max - ne.y_min, ne.n_samples)
    static = [static_rows(t, structure.row_names) for t in trajs]
    if all(s is not None for s in static):
        m.static = np.logical_and.reduce(static)
    return m

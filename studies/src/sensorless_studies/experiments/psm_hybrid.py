"""Hybrid residual on the real dVRK PSM: is physical + learned residual better on a new trajectory?

Data: the WPI logs (:func:`~sensorless_studies.experiments.psm_identification.psm_split_paths`). The physical
model is the study's OLS model identified on ``one_results`` (Coulomb smoothing ε by
cross-validation on it, or given). Rows of the report, NRMSE per coordinate on ``two_results``:

* ``physical`` — the identified model alone.
* ``hybrid_naive`` — :class:`~sensorless.learning.HybridModel` trained on ``one_results``
  (random-block early stopping inside it).
* ``hybrid_one_trajectory`` — :class:`~sensorless.learning.ValidatedHybridModel` given
  ``one_results`` only: it warns, holds out the log's last 30 % and scales the residual there.
  The excitation is periodic, so that tail repeats earlier periods and does not stand for a
  new trajectory.
* ``hybrid_validated`` — ValidatedHybridModel with early stopping and the residual scale
  chosen on a *different trajectory*: two-fold cross-fitting over the halves of
  ``two_results`` (each half is predicted by a model validated on the other half), so no
  prediction saw its own samples during validation.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from sensorless.identification import identify, torque_metrics
from sensorless.torque_models import PhysicalModel
from sensorless.learning import HybridModel, ValidatedHybridModel
from sensorless.robots.dvrk_psm import psm_structure, read_psm_log
from .psm_identification import psm_split_paths, select_smoothing

__all__ = ["psm_hybrid_study"]


def psm_hybrid_study(
    data_dir: str | Path,
    *,
    smoothing: float | str = "cv",
    hidden: Sequence[int] = (64, 64),
    window: int = 10,
    epochs: int = 60,
    seed: int = 0,
    min_gain: float = 0.02,
) -> dict:
    """Per-coordinate NRMSE on ``two_results`` of the rows in the module docstring (JSON-able)."""
    t0 = time.perf_counter()
    paths = psm_split_paths(data_dir)
    one, two = read_psm_log(paths["train"]), read_psm_log(paths["test"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # identifiability notes of the folds are not the point here
        eps = select_smoothing(one)[0] if smoothing == "cv" else float(smoothing)
        s = psm_structure(coulomb_smoothing=eps)
        phys = PhysicalModel.from_parameters(s, identify(s, one, method="ols").parameters)
    names, y = list(s.row_names), s.target(two)
    kw = dict(hidden=tuple(hidden), window=window, epochs=epochs, seed=seed, fit_physical=False)

    def table(pred: np.ndarray) -> dict:
        return dict(zip(names, map(float, torque_metrics(y, pred, names).nrmse)))

    rows: dict = {"physical": table(phys.predict(two))}
    rows["hybrid_naive"] = table(HybridModel(phys, **kw).fit(one).predict(two))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        single = ValidatedHybridModel(phys, min_gain=min_gain, **kw).fit(one)
    rows["hybrid_one_trajectory"] = table(single.predict(two))
    n = len(two)
    halves = (slice(0, n // 2), slice(n // 2, n))
    pred = np.empty_like(y)
    folds = []
    for val, test in (halves, halves[::-1]):
        m = ValidatedHybridModel(phys, min_gain=min_gain, **kw).fit(one, validation=two.take(val))
        pred[test] = m.predict(two.take(test))
        folds.append({"validated_on": f"two_results[{val.start}:{val.stop}]", "scale": m.validation_["scale"],
                      "gain": m.validation_["gain"], "best_epoch": m.history_.get("best_epoch"),
                      "epochs_run": m.history_["epochs_run"]})
    rows["hybrid_validated"] = table(pred)
    return {
        "coordinates": names,
        "test_nrmse": rows,
        "one_trajectory": {"warnings": [str(w.message) for w in caught], "scale": single.validation_["scale"],
                           "gain": single.validation_["gain"]},
        "validated_folds": folds,
        "settings": {"train": str(paths["train"]), "test": str(paths["test"]), "coulomb_smoothing": eps,
                     "hidden": list(hidden), "window": window, "epochs": epochs, "seed": seed, "min_gain": min_gain,
                     "seconds": time.perf_counter() - t0},
    }

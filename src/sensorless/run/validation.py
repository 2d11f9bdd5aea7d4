"""What a run checks and reports after the fit: the plausibility of the model (before anything is
written), the unconstrained OLS baseline on the fit's own compressed equations, the held-out scores
of the model, the baseline and the CAD model, and the floating-base checks of a measured-wrench fit."""

from __future__ import annotations

import warnings

import numpy as np
from pathlib import Path

from ..errors import SensorlessError, setting

__all__ = ["check_plausible", "ols_baseline", "held_out_scores", "blocked_scores", "floating_base_report"]


def check_plausible(result, lmi_kw: dict, accept: bool, urdf_values: str = "prior") -> None:
    """Plausibility of the fitted model (PlausibilityError, before anything is written); with ``accept``
    the problems are warned about and kept in ``result.diagnostics["implausible_accepted"]``."""
    from ..identification.plausibility import check_plausibility

    problems = check_plausibility(result, lmi_kw.get("prior"), lmi_kw.get("ellipsoids"), accept=accept,
                                  urdf_values=urdf_values)
    if problems:
        result.diagnostics["implausible_accepted"] = problems
        for p in problems:
            warnings.warn(f"implausible (kept: {setting('solver.accept_implausible')}): {p}", stacklevel=2)


def ols_baseline(fit, row_sigma):
    """Unconstrained least squares on the compressed equations of ``fit`` (a :class:`~.backend.Fit`), for
    the comparison table; None when it cannot be solved (its identifiability is not reported)."""
    from ..torque_models import PhysicalModel

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the baseline's own identifiability is not reported
            if fit.streamed is not None:  # a solve on the streamed pass's equations
                ols = fit.streamed.ols_baseline(row_sigma)
                return PhysicalModel.from_parameters(ols.structure, _fit_parameters(ols))
            ols = PhysicalModel(structure=fit.structure, method="ols", outliers="keep", weights=row_sigma,
                                check_torques=False).fit(fit.equations)
            return PhysicalModel.from_parameters(ols.structure_, _fit_parameters(ols.result_))
    except SensorlessError:
        return None


def _fit_parameters(result) -> np.ndarray:
    """The least-squares solution itself (the baseline is the unconstrained fit, not the model identify presents,
    :mod:`sensorless.identification.presented`)."""
    shown = result.diagnostics.get("presented") or {}
    return np.array(shown.get("fit_parameters", result.parameters), dtype=float)


def held_out_scores(validate, val, method: str, model, cad, baseline) -> tuple[dict, list]:
    """(result.json ``validation`` {log: {method, "cad", "ols"}}, [(title, {label: metrics})] for tables)."""
    doc, tables = {}, []
    for p, traj in zip(validate, val):
        m_id, m_cad = model.score(traj), cad.score(traj)
        cols = {"CAD": m_cad}
        doc[str(p)] = {method: m_id.to_dict(), "cad": m_cad.to_dict()}
        if baseline is not None:
            cols["OLS"] = baseline.score(traj)
            doc[str(p)]["ols"] = cols["OLS"].to_dict()
        cols[method.upper()] = m_id
        tables.append((f"held-out {Path(p).name}", cols))
    return doc, tables


def blocked_scores(result, train, lmi_kw: dict, method: str) -> tuple[dict, tuple] | None:
    """Without held-out logs: (result.json ``blocked_held_out``, its table) — the blocked held-out error
    of the training logs (:mod:`~sensorless.identification.blocked`); None when it cannot be computed."""
    from ..identification.blocked import BLOCKS, LABEL, blocked_held_out

    m = blocked_held_out(result, train, lmi_kw)
    if m is None:
        return None
    return {"label": LABEL, "blocks": BLOCKS, **m.to_dict()}, (LABEL, {method.upper(): m})


def floating_base_report(structure, result, train, val, validate) -> dict | None:
    """Measured-wrench identification: bias values, world-axis base-wrench RMSE, the CoM-vs-CoP check on
    standing windows and the contact flags, per log (result.json ``floating_base``); None otherwise."""
    if not getattr(structure, "measured_wrench", False):
        return None
    from ..identification.floating_base import base_wrench_metrics, com_cop_check
    from ..regressor.contact_inference import contact_summary

    p = result.parameters
    fb = {"contact_rows": structure.settings()["contact_rows"], "wrench_offset": structure.offset_values(p),
          "train": [], "validation": {}}
    if not getattr(structure.robot, "floating_base", False):  # e.g. a leg on a passive rail: no base rows
        fb["note"] = "fixed base: no base-wrench rows and no base pose (the measured wrench enters the joint rows)"
        fb["train"] = [{"contacts": contact_summary(structure, traj)} for traj in train]
        return fb
    for traj in train:
        fb["train"].append({"base_wrench": base_wrench_metrics(structure, p, traj),
                            "com_cop": com_cop_check(structure, p, traj),
                            "contacts": contact_summary(structure, traj)})
    for path, traj in zip(validate, val):
        fb["validation"][str(path)] = {"base_wrench": base_wrench_metrics(structure, p, traj),
                                       "com_cop": com_cop_check(structure, p, traj)}
    return fb

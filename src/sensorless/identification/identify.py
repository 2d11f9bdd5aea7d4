"""identify(): robot + logs → physically interpretable dynamic model.

Pipeline: ModelStructure (columns/rows) → streaming compression → base parameters →
solver → standard parameters → IdentificationResult.
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from ..data.outliers import OUTLIER_MODES
from ..data.trajectory import Trajectory
from ..data.validation import validate_trajectory
from ..errors import DataError, IdentifiabilityWarning, OptionError, SolverError, setting
from ..regressor.compress import compress
from ..regressor.normal_equations import NormalEquations
from ..regressor.terms import ModelStructure
from ..robot import Robot
from .base import BaseParameters, base_parameters
from .identifiability import identifiability_report
from .least_squares import (
    MIN_SINGULAR_RATIO,
    condition_number,
    joint_term_inflation,
    row_weights,
    sample_count_check,
    solve_least_squares,
    solve_truncated_svd,
)
from .metrics import metrics_from_sums
from .result import IdentificationResult
from .resampling import Resampling
from .presliding import needs_presliding_search, search_presliding
from .stribeck import StribeckCandidates, carry_prior, choose_stribeck
from .torque_channels import TorqueChannels, check_information, check_torque_channels
from .weights import check_weights
from .verdicts import compute_verdicts
from .runaway import active_bounds, gamma_guard
from .uncertainty import MAX_RELATIVE_STD, JointMotion, base_parameter_uncertainty, check_joint_motion, poorly_identified

__all__ = ["identify", "METHODS", "CONSTRAINT_RESIDUAL_RISE", "JOINT_TERM_MAX_VIF"]

METHODS = ("ols", "wls", "svd", "lmi")
# lmi: warn when the training residual exceeds the unconstrained fit's by this factor while
# bounding-ellipsoid constraints are active
CONSTRAINT_RESIDUAL_RISE = 1.2
# warn when a joint term's variance inflation factor on the log exceeds this (R² > 99.9 %)
JOINT_TERM_MAX_VIF = 1e3



def _fold_pass(structure, data: list, chunk: int, progress, gamma_folds: bool) -> tuple[list | None, NormalEquations, list]:
    """One pass over the samples for the fit's equations (their sum), the time blocks of the uncertainty
    (:mod:`.resampling`; none when the log is too short) and, with ``gamma_folds``, the cross-validation
    folds of ``--gamma auto`` (:func:`~.gamma.fold_function`: phase blocks of the excitation period):
    fold ``o · n_blocks + b`` holds fold ``o``'s samples in block ``b``. Returns (γ folds or None, whole, blocks)."""
    import functools

    from .gamma import CV_FOLDS, fold_function, split_folds
    from .resampling import compress_blocks, n_blocks_for

    outer = fold_function(data, CV_FOLDS, "auto") if gamma_folds else None
    n_outer = CV_FOLDS if gamma_folds else 1
    k = n_blocks_for(sum(len(t) for t in data), structure.n_rows, structure.n_params, len(data), n_outer)
    if k == 0:
        folds = split_folds(structure, data, CV_FOLDS, chunk, "auto", progress=progress) if gamma_folds else None
        whole = (functools.reduce(NormalEquations.merge, folds) if folds
                 else compress(structure, data, chunk=chunk, progress=progress))
        return folds, whole, []
    upper = not structure.row_map.per_sample  # the pass leaves A_r upper-triangular: mirrored once per sum
    parts = compress_blocks(structure, data, k, outer=outer, n_outer=n_outer, chunk=chunk, progress=progress,
                            mirror=not upper)
    blocks = [NormalEquations.sum(parts[b::k], left_out=False) for b in range(k)]
    folds = ([NormalEquations.sum(parts[o * k:(o + 1) * k], left_out=False) for o in range(n_outer)]
             if gamma_folds else None)
    whole = NormalEquations.sum(folds or blocks, left_out=False)
    if all(p.left_out is not None for p in parts):  # the equations left out of the fit (a law scored on every sample)
        whole.left_out = NormalEquations.sum([p.left_out for p in parts])
    for ne in [whole, *blocks, *(folds or [])] if upper else []:
        ne.mirror_upper()
    return folds, whole, blocks

def identify(
    model: Robot | ModelStructure,
    data: Trajectory | Iterable[Trajectory] | NormalEquations,
    *,
    method: str = "ols",
    weights: str | Sequence[float] | Mapping[str, float] | None = "auto",
    joint_terms: Sequence[str] = ("fv", "fc", "offset", "armature"),
    standard: str = "closest_to_prior",
    chunk: int = 2048,
    svd_rcond: float = 1e-6,
    gamma: float | str = 1e-3,
    regularization: str | None = "pullback",
    prior: np.ndarray | None = None,
    ellipsoids=None,
    lmi_options: dict | None = None,
    progress: Callable[[int], None] | None = None,
    outliers: str = "error",
    stribeck_grid: Mapping[str, Sequence[float]] | None = None,
    width_grid: Mapping[str, Sequence[float]] | None = None,
    check_torques: bool = True,
    gamma_progress: Callable[[int, int], None] | None = None,
    gamma_search: str = "bracket",
    gamma_workers: int | None = None,
    folds: Sequence[NormalEquations] | None = None,
    motion: JointMotion | None = None,
    channels: TorqueChannels | None = None,
    validated: bool = False,
) -> IdentificationResult:
    """Identify base and standard parameters from trajectories (or precompressed equations).

    ``weights`` (every method): ``"auto"`` (default) fits twice, the second time with rows
    weighted by ``1/σ_r²``, σ_r the per-joint residual of the first, unweighted fit (two-step
    weighted least squares; for "lmi" and "svd" the first fit is the unconstrained
    minimum-norm least squares, :func:`~.least_squares.two_step_sigma`); per-joint σ values
    (row order, or ``{joint: σ}``) weight by ``1/σ²``; None or "none" fits unweighted
    (ordinary least squares). See :mod:`~.weights`.
    ``method``: "ols" (= "wls" with the default weights; the default here, a building block
    that never loads cvxpy, whereas ``sensorless identify`` defaults to "lmi", which generalises
    better to other motions),
    or "svd" (minimum-norm truncated SVD over all standard parameters, relative cut-off
    ``svd_rcond``; the unconstrained baseline for contact identification), or "lmi"
    (physically consistent convex program, :func:`~.lmi.solve_lmi`, regularised toward
    ``prior`` — default the model's own inertials — with ``regularization`` and weight
    ``gamma``; ``gamma="auto"`` picks it by 5-fold cross-validation on the training data,
    :func:`~.gamma.cross_validate_gamma`, which calls ``gamma_progress(done, total)`` as it goes;
    ``gamma_search`` "bracket", "exhaustive" or "closed-form" and ``gamma_workers`` threads, as its ``search`` and
    ``workers``).
    ``progress(n)`` is called as n more samples are folded into the normal equations.
    ``ellipsoids`` and ``lmi_options`` go to the solver.
    The γ grid of ``gamma="auto"`` starts at 0; a winner at an edge of the grid, bounding
    ellipsoids that cost training residual (:data:`CONSTRAINT_RESIDUAL_RISE`, naming the
    bodies) and joint terms the log cannot separate (:data:`JOINT_TERM_MAX_VIF`) are
    reported in ``diagnostics["warnings"]`` as :class:`~sensorless.errors.IdentifiabilityWarning`.
    ``stribeck_grid``: candidate Stribeck velocities per joint (``{joint: [vs, …]}``, joints with a
    ``stribeck`` term): all candidates are compressed in the one pass and each joint's vs is chosen
    by variable projection on the compressed equations (:mod:`~.stribeck`) before the fit; the
    result's structure carries the chosen vs and ``diagnostics["stribeck_search"]`` the criterion.
    ``width_grid``: candidate transition widths of the Coulomb term per joint besides the structure's
    own ε (``{joint: [w, …]}``), chosen the same way (a fitted width must pay its BIC term).
    Precompressed ``data`` must then be the candidates' equations.
    A ``presliding`` term without a given distance is chosen per joint, or dropped, by
    :mod:`~.presliding` (two fits; ``diagnostics["presliding_search"]``).
    Precompressed ``data`` (a streamed pass, :mod:`~.streamed`) may come with the cross-validation
    ``folds`` of ``gamma="auto"`` (their sum is ``data``; candidates' equations when ``data`` is) and
    the ``motion`` / ``channels`` checks accumulated over the same samples.
    ``standard``: how to pick standard parameters from the base ones, "closest_to_prior"
    (nearest to the model's own inertials) or "min_norm".

    Trajectories are validated as the readers do (:func:`~sensorless.data.validate_trajectory`:
    shapes, dtypes, finiteness, time, joint names, units), and gross outliers are handled by
    ``outliers`` ("error" | "drop" | "keep", :mod:`~sensorless.data.outliers`), unless
    ``validated=True`` says the caller's reader already did both for this robot, on the data as
    given (``sensorless identify``'s logs: the check runs once per log). Every method
    then needs at least as many equations as base parameters and motion on every joint with
    fv/fc/armature terms (:class:`~sensorless.errors.ExcitationError` otherwise, naming the
    joint). ols/wls also refuse a rank-deficient base regressor; svd and lmi accept one (the
    truncation / the prior fixes the unexcited directions) and warn. ``diagnostics`` carries
    each base parameter's standard deviation and relative standard deviation
    (:mod:`~.uncertainty`); base parameters above 100 % and joints that barely move are listed
    in ``diagnostics["poorly_identified"]`` / ``["warnings"]`` and issued as an
    :class:`~sensorless.errors.IdentifiabilityWarning`. Before the solve, each torque row is
    checked (:mod:`~.torque_channels`: constant, dead while its joint moves, or > 100× off the
    prior's scale) unless ``check_torques=False``.
    """
    args = {k: v for k, v in locals().items() if k not in ("model", "data")}
    _check_options(method, gamma, regularization, svd_rcond, chunk, outliers, standard)
    if gamma_search not in ("bracket", "exhaustive", "closed-form"):
        raise OptionError(f"{setting('gamma_search', placeholder='bracket|exhaustive|closed-form')}: "
                          f"unknown γ search {gamma_search!r}")
    structure = model if isinstance(model, ModelStructure) else ModelStructure(model, joint_terms=tuple(joint_terms))
    if needs_presliding_search(structure):  # k per joint by BIC on a first fit's friction residual
        if isinstance(data, NormalEquations):
            raise OptionError("the 'presliding' term's distance is chosen from the logs, not precompressed equations")
        return search_presliding(identify, structure, [data] if isinstance(data, Trajectory) else data, args)
    weights = check_weights(weights, structure.row_names)
    if not isinstance(data, NormalEquations):
        motion = JointMotion(structure.robot.joint_names)
        channels = TorqueChannels(structure) if check_torques else None
        data = _validated(data, structure.robot, outliers, motion, channels, check=not validated)
    prior_note = None
    if method == "lmi" and prior is None and regularization is not None and _massless_prior(structure):
        regularization, gamma = None, 0.0  # a pull toward zero mass everywhere is no prior
        prior_note = (f"'{structure.robot.name}' has no inertial prior (every identified body is massless): "
                      "ran without regularisation; give a prior to regularise: "
                      f"{setting('prior', placeholder='...')}")
        warnings.warn(prior_note, stacklevel=2)
    if method == "lmi" and gamma == "auto":
        if isinstance(data, NormalEquations) and not folds:
            raise SolverError(f"{setting('gamma', 'auto')} needs the training trajectories, not precompressed equations")
        data = data if isinstance(data, NormalEquations) else list(data)
    cand = StribeckCandidates(structure, stribeck_grid, width_grid) if (stribeck_grid or width_grid) else None
    t0 = time.perf_counter()
    blocks: list[NormalEquations] = []
    split = isinstance(data, list) and not (folds and method == "lmi" and gamma == "auto")  # blocks (and γ's folds)
    gfolds = method == "lmi" and gamma == "auto" and not structure.row_map.per_sample
    if split and cand is None:
        got, ne, blocks = _fold_pass(structure, data, chunk, progress, gfolds)
        folds = got if gfolds else folds
    else:  # with Stribeck / width candidates the blocks are folded after the choice, at the chosen (small) size
        ne = data if isinstance(data, NormalEquations) else compress(cand or structure, data, chunk=chunk,
                                                                      progress=progress)
    t_compress = time.perf_counter() - t0
    if channels is not None:
        check_torque_channels(channels)
        check_information(ne, channels, motion)
    _check_finite_equations(ne)
    stribeck_search = None
    if cand is not None:
        choice, stribeck_search = choose_stribeck(cand, ne, weights)
        before, structure, ne = structure, cand.structure_for(choice), cand.select(ne, choice)
        folds = [cand.select(f, choice) for f in folds] if folds else folds
        prior = carry_prior(prior, before, structure)  # the search may have dropped Stribeck terms
        if split:  # a second pass at the chosen structure's size: the candidates' columns × 40 folds cost more
            got, _, blocks = _fold_pass(structure, data, chunk, None, gfolds)
            folds = got if gfolds else folds
    base = base_parameters(structure)
    sample_count_check(ne, base)
    slow: dict[str, float] = {}
    if motion is not None:
        slow = check_joint_motion(motion, structure.robot, {j: structure.terms_of(j) for j in structure.robot.term_joints}
                                  if getattr(structure, "per_joint_terms", None) else structure.joint_terms)
    report = None
    if method in ("svd", "lmi"):
        report = identifiability_report(ne, base, rcond=MIN_SINGULAR_RATIO)
    t1 = time.perf_counter()
    w = weights
    if method == "wls" and w is None:
        w = "auto"
    fit_notes: list[str] = []
    if method == "svd":
        row_w = row_weights(ne, w)
        params, svd_rank = solve_truncated_svd(ne, rcond=svd_rcond, row_weights=row_w)
        base_values = base.base(params)
        sigma = np.sqrt(ne.residual_ss(params) / max(ne.n_samples, 1))
        extra = {"svd_rank": svd_rank, "svd_rcond": svd_rcond}
        cond, base_std = condition_number(ne, base, row_w), []
    elif method == "lmi":
        from .gamma import cross_validate_gamma
        from .lmi import solve_lmi

        opts = dict(lmi_options or {})
        row_w = row_weights(ne, w)
        extra = {}
        if gamma == "auto":
            cv = cross_validate_gamma(structure, list(folds) if folds else data, period="auto", prior=prior, regularization=regularization,
                                      ellipsoids=ellipsoids, row_weights=row_w, warn=False,
                                      progress=gamma_progress, search=gamma_search, workers=gamma_workers, **opts)
            gamma = cv.gamma
            extra["gamma_selection"] = cv.to_dict()
            if cv.edge is not None:
                fit_notes.append(cv.edge_message())
            guard = gamma_guard(ne, row_w, cv.gamma, report, regularization)
            extra["gamma_guard"] = guard
            if guard["applied"]:
                gamma = guard["gamma"]
                fit_notes.append(guard["message"])
        lmi = solve_lmi(ne, structure, base=base, prior=prior, regularization=regularization, gamma=float(gamma),
                        ellipsoids=ellipsoids, row_weights=row_w, **opts)
        params = lmi.params
        base_values = base.base(params)
        sigma = np.sqrt(ne.residual_ss(params) / max(ne.n_samples, 1))
        cond, base_std = condition_number(ne, base, row_w), []
        extra["lmi"] = lmi.summary()
        extra["ellipsoid_sources"] = {b: e.get("source", "given") for b, e in
                                      (extra["lmi"].get("settings") or {}).get("ellipsoids", {}).items()}
        extra["gamma"] = float(gamma)
        cost = _constraint_cost(ne, params, lmi, row_w)
        if cost is not None:
            extra["constraint_cost"] = cost
            if cost["warn"]:
                fit_notes.append(cost.pop("message"))
            cost.pop("message", None)
        if prior_note:
            extra["prior_note"] = prior_note
    else:
        sol = solve_least_squares(ne, base, w)
        row_w = sol.row_weights
        params = _standard(base, sol.base_values, structure, standard)
        base_values, sigma, cond = sol.base_values, sol.sigma, sol.condition_number
        base_std = np.sqrt(np.maximum(sol.base_covariance_diag, 0)).tolist()
        extra = {}
    if row_w is not None:
        extra["row_weights"] = dict(zip(structure.row_names, map(float, row_w)))
    vif = joint_term_inflation(ne, base, row_w, structure.n_body_params)
    collinear = {k: v for k, v in vif.items() if not v < JOINT_TERM_MAX_VIF}
    if collinear:
        extra["joint_term_inflation"] = collinear
        fit_notes.append(_collinear_note(collinear, ne.n_samples))
    t_solve = time.perf_counter() - t1
    zero = structure.fixed_zero_index  # terms a joint does not have (e.g. a passive joint's armature): zero columns
    if zero.size:
        params = np.array(params, dtype=float)
        params[zero] = 0.0
    if not np.all(np.isfinite(params)):
        raise SolverError(f"method '{method}' returned non-finite parameters; check the data for extreme values")
    dof = max(ne.n_samples - base.rank / max(ne.A.shape[0], 1), 1.0)
    sig_dof = np.sqrt(ne.residual_ss(params) / dof)
    std = base_parameter_uncertainty(ne, base, sig_dof, rcond=MIN_SINGULAR_RATIO)
    noise = float(np.median(sig_dof)) if sig_dof.size else 0.0
    rel, poor = poorly_identified(base, np.asarray(base_values, dtype=float), std, noise)
    notes = _identifiability_notes(poor, slow, report, structure, base.rank) + fit_notes
    for note in notes:
        warnings.warn(note, IdentifiabilityWarning, stacklevel=2)
    verdicts = compute_verdicts(structure, ne, params, row_weights=row_w, method=method,
                                prior=prior, gamma=float(gamma) if method == "lmi" else 0.0,
                                regularization=regularization, lmi=extra.get("lmi"), standard=standard,
                                rank=base.rank, resampling=Resampling(blocks) if blocks else None)
    fit_params = params
    params = _present(structure, ne, base, params, prior, verdicts, row_w, method, extra)
    if blocks:
        held = _held_out_blocks(structure, ne, blocks, prior, row_w, method, gamma, regularization, extra)
        extra["held_out_blocks"] = held
        if held.get("message"):
            notes.append(held["message"])
            warnings.warn(held["message"], IdentifiabilityWarning, stacklevel=2)
    if "fit_parameters" in extra["presented"]:
        base_values = base.base(params)
    train = metrics_from_sums(
        structure.row_names, ne.residual_ss(params), ne.c, ne.y_max - ne.y_min, ne.n_samples
    )
    if method == "lmi":
        verdicts["active_bounds"] = active_bounds(extra["lmi"], fit_params, structure)  # the LMI's own
    diagnostics = {
        "rank": base.rank,
        "n_standard": structure.n_params,
        "condition_number": cond,
        "n_samples": ne.n_samples,
        "residual_sigma": dict(zip(structure.row_names, map(float, sigma))),
        "base_std": _finite_or_none(std) if method in ("svd", "lmi") else base_std,
        "base_relative_std": _finite_or_none(rel),
        "poorly_identified": poor,
        "joint_position_range": motion.ranges if motion is not None else None,
        "warnings": notes,
        **({"not_excited": report["not_excited"]} if report and report["not_excited"] else {}),
        **extra,
        **({"stribeck_search": stribeck_search} if stribeck_search else {}),
        "verdicts": verdicts,
        "compress_seconds": t_compress,
        "solve_seconds": t_solve,
    }
    settings = {
        "method": method,
        "weights": w.tolist() if isinstance(w, np.ndarray) else w,
        "standard": standard,
        "chunk": chunk,
        "outliers": outliers,
        **({"gamma": float(gamma), "regularization": regularization, "prior": "given" if prior is not None else "model"}
           if method == "lmi" else {}),
        **({"gamma_search": gamma_search} if "gamma_selection" in diagnostics else {}),
        **structure.settings(),
    }
    return IdentificationResult(method, structure, base, base_values, params, {"svd": "min_norm_svd", "lmi": "lmi"}.get(method, standard), train, diagnostics, settings,
                                equations=ne)


def _present(structure, ne, base, params, prior, verdicts, row_w, method, extra) -> np.ndarray:
    """The model every output presents (:mod:`.presented`): the verdicts' values taken at it, the fit kept in
    ``extra["presented"]["fit_parameters"]``; the fit itself when none is presented (the reason recorded)."""
    from ..regressor.joint_terms import terms_where
    from .presented import presented_parameters
    from .verdicts import present_verdicts

    p0 = structure.prior() if prior is None else np.asarray(prior, dtype=float)
    nonneg = None
    if method == "lmi":  # the LMI held these terms ≥ 0: so does the presented model
        nonneg = [structure.joint_term_index(j, t) for j in structure.robot.term_joints
                  for t in structure.terms_of(j) if t in terms_where("nonnegative")]
    new, info = presented_parameters(structure, ne, params, p0, verdicts, base.B, row_w, nonneg)
    if new is None:  # the fit is presented: an entry labelled prior whose value is not the prior's says so
        extra["presented"] = info
        present_verdicts(verdicts, structure, params, p0)
        return params
    new[structure.fixed_zero_index] = 0.0
    info["fit_parameters"] = [float(x) for x in params]
    extra["presented"] = info
    present_verdicts(verdicts, structure, new, p0)
    return new


def _held_out_blocks(structure, ne, blocks, prior, row_w, method, gamma, regularization, extra) -> dict:
    """The identified model against the prior on held-out time blocks (:meth:`~.resampling.Resampling.held_out`):
    each block predicted by the fit on the others (the regularised quadratic toward the prior, the LMI's
    linearisation, :func:`~.verdicts.regulariser_hessian`; the least-squares fit nearest the prior otherwise)
    and by the prior model; a message when the identified model predicts them worse."""
    from ..errors import setting
    from .verdicts import regulariser_hessian

    p0 = structure.prior() if prior is None else np.asarray(prior, dtype=float)
    A, b, c = ne.total(row_w)
    H = (regulariser_hessian(structure, p0, extra["lmi"], float(gamma), regularization, A, c, ne.n_samples)
         if method == "lmi" and regularization is not None and float(gamma) > 0 else np.zeros_like(A))

    def refit(Ak, bk):
        K = Ak + H
        d = np.sqrt(np.maximum(np.diag(K), 1e-300 * max(float(np.diag(K).max()), 1e-300)))
        step = np.linalg.pinv(K / np.outer(d, d), rcond=1e-10, hermitian=True) @ ((bk - Ak @ p0) / d)
        return p0 + step / d

    out = Resampling(blocks, row_w).held_out(refit, {"prior": p0})
    out = {"identified": out["refit"], "prior": out["prior"], "blocks": out["blocks"],
           "score": "relative residual Σ w‖Wπ − y‖² / Σ w‖y‖² over held-out time blocks"}
    if out["identified"] > out["prior"]:
        out["message"] = (f"the identified model predicts held-out time blocks worse than the prior model (relative "
                          f"residual {out['identified']:.3g} against {out['prior']:.3g}): the data do not support "
                          "the identified values; check the log's units, gains and unmodelled torques, or lean on the "
                          f"prior ({setting('gamma', placeholder='larger')})")
    return out


def _constraint_cost(ne: NormalEquations, params: np.ndarray, lmi, row_w) -> dict | None:
    """Training residual of the LMI solution over that of the unconstrained least squares, and the
    bodies whose bounding-ellipsoid constraint is active (density margin < 1e-3); ``warn`` when
    the residual rose by more than :data:`CONSTRAINT_RESIDUAL_RISE` with such bodies."""
    margins = {r.name: r.ellipsoid_margin for r in lmi.consistency if np.isfinite(r.ellipsoid_margin)}
    if not margins:
        return None
    wr = np.ones(ne.A.shape[0]) if row_w is None else np.asarray(row_w, dtype=float)
    free, _ = solve_truncated_svd(ne, rcond=MIN_SINGULAR_RATIO, row_weights=row_w)
    rss_free = float(wr @ np.maximum(ne.residual_ss(free), 0.0))
    rss = float(wr @ np.maximum(ne.residual_ss(params), 0.0))
    ratio = rss / max(rss_free, 1e-300 * max(rss, 1.0))
    active = [b for b, m in margins.items() if m < 1e-3]
    warn = bool(active) and ratio > CONSTRAINT_RESIDUAL_RISE
    msg = (f"the bounding-ellipsoid (density) constraints are active on {', '.join(active)} and the training "
           f"residual is {ratio:.3g}× that of an unconstrained fit: the ellipsoids probably exclude the real "
           f"bodies; use the automatic ellipsoids grown around the prior ({setting('contain_prior', True)}) or none "
           f"({setting('ellipsoids', False)})"
           if warn else None)
    return {"residual_ratio": ratio, "active_bodies": active, "warn": warn, "message": msg}


def _collinear_note(collinear: dict[str, float], n_samples: int) -> str:
    worst = ", ".join(f"{k} ({v:.2g})" for k, v in sorted(collinear.items(), key=lambda kv: -kv[1])[:6])
    return (f"{len(collinear)} joint term(s) cannot be told apart from the other parameters on this log "
            f"({n_samples} samples; variance inflation > {JOINT_TERM_MAX_VIF:.0f}): {worst}"
            + (" ..." if len(collinear) > 6 else "")
            + f"; log a longer or richer motion, or drop them ({setting('joint_terms')})")


def _massless_prior(structure: ModelStructure) -> bool:
    """True when the model carries no inertials at all (e.g. a kinematic tree such as the PSM's)."""
    nb = structure.robot.n_bodies
    return nb > 0 and not np.any(np.asarray(structure.prior())[: 10 * nb : 10] > 0)


def _standard(base: BaseParameters, pi_b: np.ndarray, structure: ModelStructure, kind: str) -> np.ndarray:
    if kind == "min_norm":
        return base.min_norm(pi_b)
    if kind == "closest_to_prior":
        return base.closest_to(pi_b, structure.prior())
    raise SolverError(f"unknown standard-parameter choice '{kind}'; use 'closest_to_prior' or 'min_norm'")


def _check_options(method, gamma, regularization, svd_rcond, chunk, outliers, standard) -> None:
    """OptionError for option values no method can use (NaN γ, unknown names, ...)."""
    if method not in METHODS:
        raise SolverError(f"unknown method '{method}'; choose from {METHODS}")
    if not (isinstance(gamma, str) and gamma == "auto"):
        try:
            g = float(gamma)
        except (TypeError, ValueError):
            raise OptionError(f"gamma must be a number >= 0 or 'auto', got {gamma!r}") from None
        if not (math.isfinite(g) and g >= 0):
            raise OptionError(f"gamma must be a finite number >= 0 or 'auto', got {gamma!r}")
    if method == "lmi" and regularization is not None and isinstance(regularization, str):
        from .regularizers import REGULARIZERS  # loads cvxpy: only the LMI uses a regulariser

        if regularization not in REGULARIZERS:
            raise OptionError(f"unknown regularization {regularization!r}; choose from {sorted(REGULARIZERS)} or None")
    if not (isinstance(svd_rcond, (int, float)) and 0 < svd_rcond < 1):
        raise OptionError(f"svd_rcond must lie in (0, 1), got {svd_rcond!r}")
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise OptionError(f"chunk must be a positive integer, got {chunk!r}")
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"outliers must be one of {list(OUTLIER_MODES)}, got {outliers!r}")
    if standard not in ("closest_to_prior", "min_norm"):
        raise SolverError(f"unknown standard-parameter choice '{standard}'; use 'closest_to_prior' or 'min_norm'")


def _validated(data, robot: Robot, outliers: str, motion: JointMotion, channels: TorqueChannels | None = None,
               check: bool = True):
    """Validate each trajectory as the readers do (unless not ``check``), note its motion and torque
    channels; a list stays a list, a generator stays lazy."""
    def one(traj) -> Trajectory:
        if not isinstance(traj, Trajectory):
            raise DataError(f"identify() takes Trajectory objects (or NormalEquations), got {type(traj).__name__}")
        traj = motion.add(validate_trajectory(traj, robot, outliers=outliers) if check else traj)
        return traj if channels is None else channels.add(traj)

    if isinstance(data, Trajectory):
        return [one(data)]
    if isinstance(data, (list, tuple)):
        return [one(t) for t in data]
    try:
        it = iter(data)
    except TypeError:
        raise DataError(f"identify() takes a Trajectory, an iterable of them or NormalEquations, got "
                        f"{type(data).__name__}") from None

    def lazy() -> Iterator[Trajectory]:
        for traj in it:
            yield one(traj)

    return lazy()


def _check_finite_equations(ne: NormalEquations) -> None:
    if not (np.all(np.isfinite(ne.A)) and np.all(np.isfinite(ne.b)) and np.all(np.isfinite(ne.c))):
        raise DataError("the identification equations overflowed (values too large to square); "
                        "check the units and magnitudes of the log")


def _finite_or_none(x) -> list:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(x, dtype=float)]


def _identifiability_notes(poor: list[dict], slow: dict[str, float], report: dict | None,
                           structure: ModelStructure, n_base: int) -> list[str]:
    """One-line warnings: poorly identified base parameters, barely moving joints, unexcited directions."""
    notes = []
    if poor:
        worst = "; ".join(
            f"{p['base_parameter']} = {p['value']:.3g} ± "
            + ("inf" if p["std"] is None else f"{p['std']:.2g} ({100 * p['relative_std']:.0f} %)"
               if p["relative_std"] is not None else f"{p['std']:.2g}")
            for p in poor[:5])
        notes.append(f"{len(poor)} of {n_base} base parameters are poorly identified "
                     f"(relative std > {100 * MAX_RELATIVE_STD:.0f} %): {worst}"
                     + (" ..." if len(poor) > 5 else ""))
    if slow:
        joints = ", ".join(f"{j} ({r:.2g})" for j, r in slow.items())
        terms = [t for t in structure.joint_terms if t in ("fv", "fc", "armature")]
        notes.append(f"joint(s) barely move (position range): {joints}; their "
                     f"{'/'.join(terms) if terms else 'body'} parameters are poorly identified")
    if report and report["not_excited"]:
        notes.append(f"{len(report['not_excited'])} base-parameter direction(s) are not excited by the data "
                     f"(e.g. {', '.join(report['not_excited'][0]['dominant_base_parameters'])}); "
                     "their values come from the regularisation / truncation, not the data")
    return notes

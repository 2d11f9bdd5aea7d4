"""Choosing the regularisation weight γ of the LMI program (:mod:`.lmi`) on held-out data.

For each γ of a grid the program is solved on training equations and scored on validation
equations that were not used to fit: ``validation_score`` is the residual
‖W π − y‖² = πᵀAπ − 2bᵀπ + c of the held-out normal equations (or its NRMSE), and the
γ with the lowest mean score over folds wins (:func:`select_gamma` for given
train/validation equations, :func:`cross_validate_gamma` for folds cut from trajectories
along whole excitation periods).

Cost. Each fold's program is compiled once with γ a cvxpy Parameter (DPP), so another γ is
only a conic solve (cvxpy reuses Clarabel's workspace). The default ``search="bracket"`` does not
solve every γ of the grid: a golden-section search on the grid indices evaluates ≈ 6 of the 20
default γ (× folds), and falls back to the whole grid when the evaluated scores are not strictly
unimodal (:func:`grid_search`). ``search="exhaustive"`` solves every γ with the conic solver, as
before. ``search="closed-form"`` is the bracket search in which a (fold, γ) whose unconstrained
minimiser satisfies every constraint takes that exact solution without a conic solve
(:mod:`.unconstrained`; TALOS: 5 conic solves instead of 30). It is more accurate than the conic
solver where the data barely see a direction, so it can pick another γ where the CV scores of
neighbouring γ differ by less than the solver's tolerance (the Panda demo: 1e-4 instead of
3.16e-5, held-out NRMSE 2.5799 % instead of 2.5800 %); hence not the default.
"""

from __future__ import annotations

import functools
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ..data.periodicity import excitation_period
from ..data.trajectory import Trajectory
from ..errors import DataError, IdentifiabilityWarning, SolverError
from ..regressor.compress import compress
from ..data.blocks import blocked_folds
from ..regressor.normal_equations import NormalEquations, compress_folds
from ..regressor.terms import ModelStructure
from .ellipsoids import resolve_ellipsoids
from .lmi import DEFAULT_GAMMAS, LmiProblem, build_lmi
from .unconstrained import regularizer_metric, unconstrained_solution

__all__ = ["CV_FOLDS", "GAMMA_SEARCHES", "GammaSelection", "cross_validate_gamma", "fold_function", "grid_search", "select_gamma", "validation_score"]

GAMMA_SEARCHES = ("bracket", "exhaustive", "closed-form")
CV_FOLDS = 5  # folds of ``--gamma auto``
_BRACKET_MIN = 6  # grids shorter than this are scanned whole
_GOLDEN = 0.3819660112501051  # 1 − 1/φ


@dataclass
class GammaSelection:
    """Held-out score per γ (``scores``, mean over folds; ``fold_scores`` (n_γ, n_folds));
    nan for a γ the search did not evaluate, inf where a solve failed. ``search`` is the
    search that ran ("exhaustive", "bracket" or "bracket+exhaustive": the fallback),
    ``n_solves`` the number of conic LMI solves, ``n_closed_form`` the (fold, γ) pairs solved in closed
    form because no constraint was active (:mod:`.unconstrained`), ``seconds`` the wall time."""

    gamma: float
    gammas: np.ndarray
    scores: np.ndarray
    fold_scores: np.ndarray
    score: str
    failures: dict[float, str] = field(default_factory=dict)
    search: str = "exhaustive"
    n_solves: int = 0
    seconds: float = float("nan")
    n_closed_form: int = 0

    @property
    def edge(self) -> str | None:
        """"upper" if the largest γ of the grid won, "lower" if the smallest did and it is
        not 0 (0 is the natural bound: no prior), else None. An edge means the best γ may
        lie outside the grid."""
        g = np.asarray(self.gammas, dtype=float)
        if len(g) < 2:
            return None
        if self.gamma == g.max():
            return "upper"
        if self.gamma == g.min() and self.gamma > 0:
            return "lower"
        return None

    def edge_message(self) -> str | None:
        """One-line warning text when :attr:`edge` is set."""
        if self.edge is None:
            return None
        finite = self.scores[np.isfinite(self.scores)]
        trend = f"held-out {self.score} {finite.min():.3g}" if finite.size else ""
        if self.edge == "upper":
            return (f"cross-validation picked the largest γ of its grid ({self.gamma:g}; {trend}): the prior may "
                    "deserve more weight than the grid allows; extend the grid upward or check the data")
        return (f"cross-validation picked the smallest γ of its grid ({self.gamma:g}; {trend}) while the score may "
                "still be falling; extend the grid downward (include 0, no prior)")

    def to_dict(self) -> dict:
        """Plain types; a γ the search did not evaluate has score None and ``evaluated`` False."""
        return {
            "gamma": self.gamma,
            "edge": self.edge,
            "gammas": self.gammas.tolist(),
            "scores": [None if np.isnan(v) else float(v) for v in self.scores],
            "fold_scores": [[None if np.isnan(v) else float(v) for v in row] for row in self.fold_scores],
            "evaluated": (~np.isnan(self.scores)).tolist(),
            "score": self.score,
            "search": self.search,
            "n_solves": self.n_solves,
            "n_closed_form": self.n_closed_form,
            "seconds": self.seconds,
            "failures": {str(k): v for k, v in self.failures.items()},
        }


def validation_score(ne: NormalEquations, params: np.ndarray, score: str = "residual", row_weights=None) -> float:
    """Held-out error of ``params`` on ``ne``.

    "residual": ``Σ_r w_r ‖W_r π − y_r‖² / Σ_r w_r ‖y_r‖²``; "nrmse": mean over rows with a
    non-zero measured range of ``RMSE_r / range_r``.
    """
    ss = ne.residual_ss(params)
    if score == "residual":
        w = np.ones(len(ss)) if row_weights is None else np.asarray(row_weights, dtype=float)
        return float(w @ ss / max(w @ ne.c, 1e-300))
    if score == "nrmse":
        rng = ne.y_max - ne.y_min
        ok = rng > 0
        return float(np.mean(np.sqrt(ss[ok] / max(ne.n_samples, 1)) / rng[ok]))
    raise ValueError(f"unknown score '{score}'; use 'residual' or 'nrmse'")


def _unimodal(values: Sequence[float]) -> bool:
    """Every value finite, strictly decreasing up to the minimum and strictly increasing after it."""
    v = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(v)):
        return False
    m = int(np.argmin(v))
    return bool(np.all(np.diff(v[: m + 1]) < 0) and np.all(np.diff(v[m:]) > 0))


def grid_search(n: int, evaluate: Callable[[int], float], search: str = "bracket") -> str:
    """Call ``evaluate(i)`` (i = 0 … n−1, each at most once) on enough grid points to find its argmin.

    "exhaustive": every point. "bracket" (or "closed-form"): golden-section search on the indices — the bracket
    [lo, hi] that holds the minimum of a unimodal curve shrinks by 1/φ per step, about 6 of 20
    points — then the winner's neighbours. If the evaluated values are not strictly unimodal in
    index order (a tie, a failed solve, a second dip) every point is evaluated, so the argmin is
    the exhaustive one. A second valley among the points it never evaluated (e.g. on the side a
    first comparison discarded) is not seen by that check: there the bracket can miss the grid's
    argmin. Grids shorter than 6 are scanned whole.
    Returns the search that ran: "exhaustive", "bracket" or "bracket+exhaustive".
    """
    if search not in GAMMA_SEARCHES:
        raise ValueError(f"unknown γ search '{search}'; use one of {', '.join(GAMMA_SEARCHES)}")
    seen: dict[int, float] = {}

    def f(i: int) -> float:
        if i not in seen:
            seen[i] = float(evaluate(i))
        return seen[i]

    if search == "exhaustive" or n < _BRACKET_MIN:
        for i in range(n):
            f(i)
        return "exhaustive"
    lo, hi = 0, n - 1
    while hi - lo > 3:
        d = int(round(_GOLDEN * (hi - lo)))
        a, b = lo + d, max(hi - d, lo + d + 1)
        if f(a) <= f(b):
            hi = b
        else:
            lo = a
    best = min(range(lo, hi + 1), key=f)
    for j in (best - 1, best + 1):
        if 0 <= j < n:
            f(j)
    if _unimodal([seen[i] for i in sorted(seen)]):
        return "bracket"
    for i in range(n):
        f(i)
    return "bracket+exhaustive"


class _FoldScorer:
    """``scorer(i)``: the mean held-out score over folds of grid point ``i``, filling ``fold_scores``
    (one compiled :class:`LmiProblem` per fold, re-solved per γ; a failed solve scores inf). With
    ``workers`` > 1 the folds are solved in threads (the conic solver releases the GIL; each
    thread touches only its own fold's problem, so the numbers are those of a serial run)."""

    def __init__(self, problems: Sequence[LmiProblem], vals: Sequence[NormalEquations], gammas: np.ndarray,
                 score: str, row_weights, solver: str | None, tick: Callable[[], None] = lambda: None,
                 workers: int = 1, closed_form: bool = False) -> None:
        self.problems, self.vals, self.gammas, self.score = problems, vals, gammas, score
        self.row_weights, self.solver, self.tick = row_weights, solver, tick
        self.workers = max(1, min(int(workers), len(problems)))
        self.closed_form = closed_form
        self._metrics: dict[int, np.ndarray | None] = {}
        self.fold_scores = np.full((len(gammas), len(problems)), np.nan)
        self.failures: dict[float, str] = {}
        self.n_solves = 0
        self.n_closed_form = 0

    def _unconstrained(self, f: int, g: float) -> np.ndarray | None:
        if not self.closed_form:
            return None
        if f not in self._metrics:
            self._metrics[f] = regularizer_metric(self.problems[f])
        if self._metrics[f] is None:
            return None
        return unconstrained_solution(self.problems[f], g, self._metrics[f])

    def _one(self, f: int, g: float) -> tuple[float, str | None]:
        try:
            sol = self.problems[f].solve(g, solver=self.solver)
        except SolverError as exc:
            return np.inf, str(exc)
        return validation_score(self.vals[f], sol.params, self.score, self.row_weights), None

    def __call__(self, i: int) -> float:
        g = float(self.gammas[i])
        results: dict[int, tuple[float, str | None]] = {}
        for f in range(len(self.problems)):  # no constraint active: the exact minimiser, no conic solve
            params = self._unconstrained(f, g)
            if params is not None:
                results[f] = (validation_score(self.vals[f], params, self.score, self.row_weights), None)
                self.n_closed_form += 1
                self.tick()
        todo = [f for f in range(len(self.problems)) if f not in results]
        if self.workers > 1 and len(todo) > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(min(self.workers, len(todo))) as ex:
                for f, r in zip(todo, ex.map(lambda f: self._one(f, g), todo)):
                    results[f] = r
                    self.tick()
        else:
            for f in todo:
                results[f] = self._one(f, g)
                self.tick()
        for f, (val, err) in results.items():
            self.fold_scores[i, f] = val
            if err is not None:
                self.failures[g] = err
        self.n_solves += len(todo)
        return float(self.fold_scores[i].mean())

    def select(self, search: str, warn: bool) -> GammaSelection:
        ran = grid_search(len(self.gammas), self, search)
        scores = self.fold_scores.mean(axis=1)  # nan: not evaluated, inf: a fold failed
        if not np.any(np.isfinite(scores)):
            raise SolverError(f"no gamma could be solved: {self.failures}")
        best = int(np.argmin(np.where(np.isnan(scores), np.inf, scores)))
        sel = GammaSelection(float(self.gammas[best]), self.gammas, scores, self.fold_scores, self.score,
                             self.failures, ran, self.n_solves, n_closed_form=self.n_closed_form)
        if warn and sel.edge is not None:
            warnings.warn(sel.edge_message(), IdentifiabilityWarning, stacklevel=3)
        return sel


def select_gamma(
    ne_train: NormalEquations,
    ne_val: NormalEquations,
    structure: ModelStructure,
    gammas: Sequence[float] = DEFAULT_GAMMAS,
    *,
    score: str = "residual",
    solver: str | None = None,
    warn: bool = True,
    search: str = "bracket",
    **build_kwargs: Any,
) -> GammaSelection:
    """The γ whose solution on ``ne_train`` has the lowest :func:`validation_score` on ``ne_val``.

    ``build_kwargs`` as :func:`solve_lmi` (regularization, constraints, ellipsoids, ...).
    The program is compiled once; γ is a parameter. ``search``: "bracket" (default),
    "exhaustive" or "closed-form" (module docstring). A winner at an edge of the grid
    (:attr:`GammaSelection.edge`) issues an :class:`~sensorless.errors.IdentifiabilityWarning`
    unless ``warn=False``.
    """
    t0 = time.perf_counter()
    gammas = np.asarray(gammas, dtype=float)
    prob = build_lmi(ne_train, structure, **build_kwargs)
    sel = _FoldScorer([prob], [ne_val], gammas, score, build_kwargs.get("row_weights"), solver,
                      closed_form=search == "closed-form").select(search, warn)
    sel.seconds = time.perf_counter() - t0
    return sel


def split_folds(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory] | Sequence[NormalEquations],
    n_folds: int,
    chunk: int,
    period: float | str | None,
    tick: Callable[[], None] = lambda: None,
    progress: Callable[[int], None] | None = None,
) -> list[NormalEquations]:
    """The ``n_folds`` cross-validation folds of ``data`` as normal equations. With a ``period``
    (``"auto"``: :func:`~sensorless.data.periodicity.excitation_period`), fold f holds the samples in
    phase block f of the period; without, the concatenated logs are cut into ``n_folds`` contiguous
    pieces. One pass over the samples (:func:`~sensorless.regressor.normal_equations.compress_folds`):
    the masks of the fit are the whole log's, and the folds sum to its equations. Given normal
    equations (at least 2) are the folds. ``progress(n)``: as :func:`compress`'s."""
    items = [data] if isinstance(data, Trajectory) else list(data)
    if items and all(isinstance(i, NormalEquations) for i in items):
        if len(items) < 2:
            raise DataError("cross-validation needs at least 2 folds of normal equations")
        return items  # type: ignore[return-value]
    trajs: list[Trajectory] = items  # type: ignore[assignment]
    fold_of = fold_function(trajs, n_folds, period)
    if structure.row_map.per_sample:  # contacts fold their own equations: each fold compressed from its samples
        folds = [compress(structure, _fold_parts(trajs, fold_of, f), chunk=chunk, progress=progress)
                 for f in range(n_folds)]
    else:
        folds = compress_folds(structure, trajs, fold_of, n_folds, chunk=chunk, progress=progress)
    for _ in folds:
        tick()
    return folds


def fold_function(trajs: list[Trajectory], n_folds: int, period: float | str | None):
    """``fold_of(k, traj)(start, stop)``: the cross-validation fold of samples [start, stop) of the k-th log
    (:func:`split_folds`: phase blocks of ``period``, or contiguous pieces of the concatenated logs)."""
    total = sum(len(t) for t in trajs)
    if n_folds < 2 or total < 2 * n_folds:
        raise DataError(f"cannot split {total} samples into {n_folds} folds (need n_folds >= 2)")
    if period == "auto":
        period = excitation_period(trajs[0])
    if period is not None:
        if not float(period) > 0:  # type: ignore[arg-type]
            raise DataError(f"period must be positive, got {period}")
        blocks = [np.floor(((t.t - t.t[0]) % period) / period * n_folds).astype(int) for t in trajs]  # type: ignore[operator]
        for f in range(n_folds):
            if not any(np.any(b == f) for b in blocks):
                raise DataError(f"no sample falls in phase block {f} of {n_folds}; is the period of {period} s right?")
        fold_of = lambda k, t: lambda lo, hi: blocks[k][lo:hi]  # noqa: E731
    else:
        labels = blocked_folds([len(t) for t in trajs], n_folds)
        fold_of = lambda k, t: lambda lo, hi: labels[k][lo:hi]  # noqa: E731
    return fold_of


def _fold_parts(trajs: list[Trajectory], fold_of, f: int) -> list[Trajectory]:
    """The samples of fold ``f``, one trajectory per log that has some."""
    parts = []
    for k, t in enumerate(trajs):
        mask = fold_of(k, t)(0, len(t)) == f
        if mask.any():
            parts.append(t.take(mask))
    return parts


def cross_validate_gamma(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory] | Sequence[NormalEquations],
    gammas: Sequence[float] = DEFAULT_GAMMAS,
    *,
    n_folds: int = CV_FOLDS,
    score: str = "residual",
    period: float | str | None = None,
    solver: str | None = None,
    chunk: int = 2048,
    warn: bool = True,
    search: str = "bracket",
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    **build_kwargs: Any,
) -> GammaSelection:
    """K-fold cross-validation of γ on contiguous folds (what ``--gamma auto`` runs).

    The training samples (one trajectory or several, in order) are cut into ``n_folds``
    contiguous blocks, each compressed once; fold ``f`` trains on the sum of the other
    blocks' normal equations (they are additive) and scores on block ``f``
    (:func:`validation_score`). Contiguous blocks keep neighbouring, correlated samples
    on one side of the split. A periodic excitation (Fourier series) that was logged for
    several periods repeats itself, so a time block has a twin in the training folds;
    give its ``period`` [s] (or "auto": :func:`excitation_period` of the first trajectory;
    no period found → time blocks) and the blocks are contiguous in phase
    ``(t − t0) mod period`` instead. Precompressed folds may be passed instead of trajectories. The returned γ
    minimises the mean score over folds; ``build_kwargs`` as :func:`solve_lmi`. The default
    grid starts at γ = 0 (no prior); a winner at an edge of the grid warns (``warn``, see
    :func:`select_gamma`). ``search``: "bracket" (default: a golden-section search on the grid,
    the whole grid when its scores are not unimodal) or "exhaustive" (:func:`grid_search`).
    ``progress(done, total)`` is called after each fold is compressed and each LMI solved, with
    total = the exhaustive count n_folds · (1 + n_γ) (n_folds · n_γ for precompressed folds); a
    bracket search that ends early reports ``(total, total)`` last. ``workers`` threads solve the
    folds of one γ side by side (default: one per available core; the numbers do not depend on it).
    """
    t0 = time.perf_counter()
    gammas = np.asarray(gammas, dtype=float)
    items = [data] if isinstance(data, Trajectory) else list(data)
    given = bool(items) and all(isinstance(i, NormalEquations) for i in items)
    total = (len(items) if given else n_folds) * len(gammas) + (0 if given else n_folds)
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    folds = split_folds(structure, items, n_folds, chunk, period, tick)
    ellipsoids = build_kwargs.pop("ellipsoids", None)
    prior = build_kwargs.get("prior")
    ell = resolve_ellipsoids(structure.robot, ellipsoids, prior=structure.prior() if prior is None else prior)
    problems = []
    for f in range(len(folds)):
        train = functools.reduce(NormalEquations.merge, [folds[i] for i in range(len(folds)) if i != f])
        problems.append(build_lmi(train, structure, ellipsoids=ell or False, **build_kwargs))
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    scorer = _FoldScorer(problems, folds, gammas, score, build_kwargs.get("row_weights"), solver, tick, workers,
                         closed_form=search == "closed-form")
    sel = scorer.select(search, warn)
    sel.seconds = time.perf_counter() - t0
    if progress is not None and done[0] < total:
        progress(total, total)
    return sel

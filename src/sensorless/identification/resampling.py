"""Uncertainty from the data's own spread: a blocked jackknife over time blocks and logs.

The linear covariance ``s² aᵀA⁺a`` (:mod:`.verdicts`) assumes independent, exactly known rows: q,
v and v̇ without error, white torque noise, only the modelled terms producing torque. Real logs
break every one of these (quantized encoders, 4-decimal rounding, differentiated noise, holding
current on a still joint, unmodelled flexibility), and then that interval is far too narrow. Here
the estimate is recomputed with each independent part of the data left out, and its spread is the
uncertainty:

* **parts**: each log is cut into contiguous time *blocks* (:func:`block_index`; a block never
  spans two logs, so separate logs are separate parts); each block is compressed into its own
  normal equations in the one pass of the fit (:func:`compress_blocks`, whose sum is the whole
  log's equations), so a refit is ``(A − A_k, b − b_k)``: nothing per sample is kept;
* **jackknife**: with ``G`` parts and ``θ_(k)`` the estimate without part ``k``,
  ``var = (G − 1)/G · Σ_k (θ_(k) − θ̄)²`` (Efron & Stein; blocked: Künsch 1989);
* **block length from the residual's correlation** (Flyvbjerg & Petersen 1989): when the errors
  are correlated over longer than a block, neighbouring blocks are not independent and the
  jackknife under-states the variance; merging ``g`` consecutive blocks into one part raises it
  until the parts outgrow the correlation. The spread is evaluated for ``g = 1, 2, 4, …`` while at
  least :data:`MIN_PARTS` parts remain, and the largest is kept (``parts`` records which);
* **intervals**: ``θ̂ ± t_{0.975, G−1} · std`` (Student's t with the parts' degrees of freedom);
* **options the data cannot decide** (e.g. the wrench-offset model): :func:`option_spread` adds
  half the range of the estimates across the options to the standard deviation.

Quantities the data leave unseen (a direction in the null space of ``A − A_k``) get ``std = inf``
when removing one block makes them so: a quantity seen only in one block of the log is not
determined by independent parts. Coarser parts only widen the quantities they still see (a joint
that moves in one segment of a one-joint-at-a-time log is judged on the blocks within it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..regressor.normal_equations import NormalEquations

__all__ = ["pinv_parts", "N_BLOCKS", "MIN_PARTS", "MEMORY_BUDGET", "Resampling", "block_index", "n_blocks_for",
           "compress_blocks", "linear_estimates", "option_spread", "t_quantile"]

N_BLOCKS = 16  #: contiguous time blocks over all logs (at most; fewer for short logs or large models)
MAX_FOLDS = 40  #: blocks × the folds of a second partition (γ's cross-validation) kept apart in one pass
MIN_PARTS = 4  #: the fewest parts a jackknife is computed on
MIN_BLOCK_SAMPLES = 20  #: a block holds at least this many samples
MEMORY_BUDGET = 256e6  #: bytes the blocks' normal equations may take together


def n_blocks_for(n_samples: int, rows: int, n_params: int, n_logs: int = 1, outer: int = 1) -> int:
    """How many blocks: :data:`N_BLOCKS` (at least one per log), fewer when a block would hold less than
    :data:`MIN_BLOCK_SAMPLES` samples, the blocks × ``outer`` folds exceed :data:`MAX_FOLDS` (each is
    folded and mirrored apart) or their equations the memory budget;
    0 when fewer than :data:`MIN_PARTS` blocks are possible (no resampling)."""
    per = 8.0 * rows * n_params * (n_params + 1) * max(outer, 1)
    k = min(max(N_BLOCKS, n_logs), MAX_FOLDS // max(outer, 1), n_samples // MIN_BLOCK_SAMPLES,
            int(MEMORY_BUDGET // max(per, 1.0)))
    return int(k) if k >= MIN_PARTS else 0


def block_index(lengths: Sequence[int], n_blocks: int) -> list[np.ndarray]:
    """Per log, the block of each sample (0 … n_blocks − 1, contiguous, in time order): the blocks are
    shared among the logs in proportion to their lengths (at least one each), and cut equally within a log."""
    lengths = [int(n) for n in lengths]
    total = max(sum(lengths), 1)
    share = [max(1, int(round(n_blocks * n / total))) if n else 0 for n in lengths]
    while sum(share) > max(n_blocks, sum(1 for n in lengths if n)):  # rounding up overshot: take from the largest
        share[int(np.argmax(share))] -= 1
    out, first = [], 0
    for n, s in zip(lengths, share):
        edges = np.linspace(0, n, s + 1).round().astype(int) if s else np.zeros(1, dtype=int)
        out.append(first + np.searchsorted(edges, np.arange(n), side="right") - 1)
        first += s
    return out


def compress_blocks(structure, trajs: list, n_blocks: int, *, outer=None, n_outer: int = 1, chunk: int = 2048,
                    progress=None, mirror: bool = True) -> list[NormalEquations]:
    """The blocks' normal equations in one pass (their sum: the whole log's). ``outer(k, traj)`` (with
    ``n_outer``): a second partition, e.g. the cross-validation folds of γ; fold ``o · n_blocks + b`` then
    holds the samples of outer fold ``o`` and block ``b`` (merge over ``b`` for the outer folds, over
    ``o`` for the blocks). Structures that fold their own equations (contacts) compress each part apart.
    ``mirror=False``: the folds' A_r left upper-triangular where the pass allows (``NormalEquations.mirror_upper``
    after summing them; a contact structure's are complete whatever it is)."""
    from ..regressor.compress import compress
    from ..regressor.normal_equations import compress_folds

    idx = block_index([len(t) for t in trajs], n_blocks)
    if outer is None:
        fold_of = lambda k, t: lambda lo, hi: idx[k][lo:hi]  # noqa: E731
    else:
        fold_of = lambda k, t: (lambda o: lambda lo, hi: o(lo, hi) * n_blocks + idx[k][lo:hi])(outer(k, t))  # noqa: E731
    n = n_blocks * max(n_outer, 1)
    if not structure.row_map.per_sample:
        return compress_folds(structure, trajs, fold_of, n, chunk=chunk, progress=progress, mirror=mirror)
    out = []
    for f in range(n):
        parts = [t.take(m) for k, t in enumerate(trajs) if (m := fold_of(k, t)(0, len(t)) == f).any()]
        out.append(compress(structure, parts, chunk=chunk, progress=progress) if parts
                   else NormalEquations.zeros(structure.n_rows, structure.n_params))
    return out


#: Student's t quantiles of a two-sided 95 % interval, 1 … 30 degrees of freedom
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
         2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042)


def t_quantile(dof: int) -> float:
    """Student's t quantile of a two-sided 95 % interval with ``dof`` degrees of freedom (a table to 30, then
    the Cornish–Fisher expansion about the normal quantile: no SciPy import on the fit's path)."""
    nu = max(int(dof), 1)
    if nu <= len(_T975):
        return _T975[nu - 1]
    z = 1.959963984540054
    return z + (z**3 + z) / (4 * nu) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * nu**2)


def pinv_parts(A: np.ndarray, null_cutoff: float):
    """Equilibration ``d``, the kept eigenpairs (λ > ``null_cutoff`` × λ_max) and the null basis of
    ``D⁻¹AD⁻¹`` (D = diag(√A_ii); a zero diagonal entry is a dead direction)."""
    diag = np.diag(A).copy()
    top = max(float(diag.max()) if diag.size else 0.0, 1e-300)
    dead = diag <= 1e-14 * top
    d = np.sqrt(np.where(dead, 1.0, diag))
    Ah = A / np.outer(d, d)
    Ah[dead, :] = Ah[:, dead] = 0.0
    lam, V = np.linalg.eigh(0.5 * (Ah + Ah.T))
    keep = lam > null_cutoff * max(float(lam[-1]) if lam.size else 0.0, 1e-300)
    return d, lam[keep], V[:, keep], V[:, ~keep]


def _solve(A: np.ndarray, b: np.ndarray, Q: np.ndarray, null_cutoff: float, null_fraction: float) -> np.ndarray:
    """``Q A⁺ b`` per row of ``Q`` (equilibrated pseudo-inverse), inf where a row reaches ``A``'s null space."""
    d, lam, Vk, N0 = pinv_parts(A, null_cutoff)
    Qh = Q / d
    est = (Qh @ Vk) @ ((Vk.T @ (b / d)) / lam)
    null = np.linalg.norm(Qh @ N0, axis=1) if N0.shape[1] else np.zeros(len(Q))
    return np.where(null > null_fraction * np.linalg.norm(Qh, axis=1), np.inf, est)


def linear_estimates(null_cutoff: float = 1e-10, null_fraction: float = 1e-6) -> Callable:
    """The data-alone estimator of linear quantities ``Q π`` (rows of ``Q``): ``(A, b, Q) ↦ Q A⁺ b``
    (equilibrated; inf for a quantity the equations do not see), the one :class:`Resampling` refits."""
    return lambda A, b, Q: _solve(A, b, Q, null_cutoff, null_fraction)


@dataclass
class Resampling:
    """The blocks' normal equations of a fit (``blocks``, in time order, logs one after another) and the
    jackknife over them (module docstring)."""

    blocks: list[NormalEquations]
    row_weights: np.ndarray | None = None
    #: the part size of the last :meth:`spread` that gave the largest spread for the most quantities
    chosen: dict = field(default_factory=dict)

    def _totals(self):
        w = self.row_weights
        return [ne.total(w)[:2] for ne in self.blocks if ne.n_samples > 0]

    def spread(self, Q: np.ndarray, estimate: Callable | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(std, half_width)`` of the estimates ``estimate(A, b, Q)`` (default :func:`linear_estimates`)
        for each row of ``Q``: the largest blocked-jackknife standard deviation over the part sizes, and the
        95 % half-width ``t_{G−1} · std`` of that part size. inf where a part's removal leaves a quantity unseen."""
        estimate = estimate or linear_estimates()
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        parts = self._totals()
        A = sum(a for a, _ in parts)
        b = sum(v for _, v in parts)
        best = np.full(len(Q), -1.0)
        half = np.full(len(Q), np.inf)
        wins: list[tuple[int, int, int]] = []
        g = 1
        while len(parts) >= MIN_PARTS:
            with np.errstate(invalid="ignore", over="ignore"):
                est = np.array([estimate(A - a, b - v, Q) for a, v in parts])
                G = len(parts)
                seen = np.isfinite(est).all(axis=0)
                mean = np.where(seen, est, 0.0).mean(axis=0)
                var = (G - 1) / G * ((np.where(seen, est, 0.0) - mean) ** 2).sum(axis=0)
            std = np.where(seen, np.sqrt(var), np.inf if g == 1 else -1.0)  # coarser parts only widen what is seen
            up = std > best
            wins.append((int(up.sum()), G, g))
            half = np.where(up, t_quantile(G - 1) * std, half)
            best = np.maximum(best, std)
            parts = [(sum(a for a, _ in parts[i:i + 2]), sum(v for _, v in parts[i:i + 2]))
                     for i in range(0, len(parts) - len(parts) % 2, 2)]
            g *= 2
        if not wins:  # too few parts
            self.chosen = {}
            return np.full(len(Q), np.nan), np.full(len(Q), np.nan)
        n, G, g = max(wins)  # the part size that widened the most quantities
        self.chosen = {"parts": G, "blocks_per_part": g}
        return best, half

    def held_out(self, refit: Callable, fixed: dict[str, np.ndarray]) -> dict:
        """Blocked held-out error: each block scored by ``refit(A, b)`` (the model fitted on the other blocks'
        weighted equations) and by each ``fixed`` model (e.g. the prior), as the relative residual
        ``Σ_k Σ_r w_r ‖W_r π − y_r‖² / Σ_k Σ_r w_r ‖y_r‖²`` over the blocks: ``{"refit": x, name: y, …, "blocks": K}``."""
        w = np.ones(self.blocks[0].A.shape[0]) if self.row_weights is None else np.asarray(self.row_weights, float)
        live = [ne for ne in self.blocks if ne.n_samples > 0]
        A = sum(ne.total(w)[0] for ne in live)
        b = sum(ne.total(w)[1] for ne in live)
        energy = sum(float(w @ ne.c) for ne in live)
        out = {"refit": 0.0, **{k: 0.0 for k in fixed}, "blocks": len(live)}
        for ne in live:
            Ak, bk, _ = ne.total(w)
            out["refit"] += float(w @ ne.residual_ss(refit(A - Ak, b - bk)))
            for k, pi in fixed.items():
                out[k] += float(w @ ne.residual_ss(pi))
        for k in ["refit", *fixed]:
            out[k] /= max(energy, 1e-300)
        return out

    def settings(self) -> dict:
        return {"method": "blocked jackknife over contiguous time blocks and logs (largest over part sizes)",
                "blocks": len(self.blocks), "min_parts": MIN_PARTS, **self.chosen}


def option_spread(std: np.ndarray, estimates: Sequence[np.ndarray]) -> np.ndarray:
    """``std`` widened by an undecidable modelling option: ``√(std² + (range/2)²)``, ``range`` the spread of
    the quantity's estimates across the options (``estimates``: one array per option)."""
    E = np.asarray(estimates, dtype=float)
    rng = E.max(axis=0) - E.min(axis=0) if len(E) else 0.0
    return np.sqrt(np.asarray(std, dtype=float) ** 2 + (rng / 2) ** 2)

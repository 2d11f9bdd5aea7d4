"""Normal equations of the identification problem, folded from trajectories in this process.

Stacking W π ≈ y over N samples would need N · rows · p floats. Instead each chunk of
samples is folded into per-row normal equations

    A_r = Σ_i W_{i,r}ᵀ W_{i,r},   b_r = Σ_i W_{i,r}ᵀ y_{i,r},   c_r = Σ_i y_{i,r}²

one set per equation row r (per joint). Memory is O(rows · p²), independent of N.
Keeping rows separate lets weighted least squares rescale rows afterwards
(A = Σ_r A_r / σ_r²) and gives per-joint residuals ‖W_r π − y_r‖² = πᵀA_rπ − 2πᵀb_r + c_r
without a second pass over the data. Range statistics of y are kept for NRMSE.

Speed (the fold is the only O(N p²) work besides the regressor itself):

* each A_r is accumulated from strided views of the chunk, no copies: ``M.T @ M``, which NumPy
  hands to BLAS SYRK, for the body block, and small products for the joint-term blocks (the lower
  cross block is mirrored once at the end of :func:`compress_trajectories`);
* row r of Pinocchio's joint-torque regressor is zero outside the bodies of the subtree of
  r's joint (τ_j = S_jᵀ Σ_{b ∈ subtree(j)} f_b(π_b)); Pinocchio numbers joints depth-first, so
  that is one contiguous column range per row (:meth:`ModelStructure.row_body_columns`) and only
  that block and the row's joint terms are folded;
* BLAS is pinned to one thread while compressing (threadpoolctl): the chunk products are small,
  and threaded BLAS under CPU contention was measured 39× slower;
* with ``overlap=True`` the fold of chunk k runs in a helper thread (BLAS releases the GIL)
  while the Python loop evaluates the regressor of chunk k + 1 (double buffering); by default
  only when a core is idle.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Iterable, Iterator

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError
from .terms import ModelStructure

__all__ = ["NormalEquations", "RowMajorFold", "compress_folds", "compress_trajectories", "fold_chunk", "fold_into", "iter_trajectories", "one_blas_thread", "syrk_fold"]


def _dsyrk():
    from scipy.linalg.blas import dsyrk  # imported on use (CLI start-up)

    return dsyrk


def _mirror(U: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose upper triangle is that of U."""
    return np.triu(U) + np.triu(U, 1).T


def syrk_fold(M: np.ndarray) -> np.ndarray:
    """MᵀM for M (n, k) by BLAS SYRK on the upper triangle, returned as the full symmetric (k, k).

    ``dsyrk`` with ``trans=0`` on the Fortran view ``M.T`` (k, n) computes a·aᵀ = MᵀM without copying a
    C-contiguous M (``trans=1`` on a column-major M is used when M is already column-major); only the
    upper triangle is computed and it is mirrored here.
    """
    M = np.asarray(M, dtype=float)
    if M.shape[0] == 0:
        return np.zeros((M.shape[1], M.shape[1]))
    if M.flags.f_contiguous and not M.flags.c_contiguous:
        return _mirror(_dsyrk()(1.0, M, trans=1, lower=0))
    return _mirror(_dsyrk()(1.0, np.ascontiguousarray(M).T, trans=0, lower=0))


@contextmanager
def one_blas_thread():
    """BLAS (and OpenMP) limited to one thread inside the block (threadpoolctl), restored after."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield



@dataclass
class NormalEquations:
    """Per-row normal equations of W π ≈ y (see module docstring)."""

    A: np.ndarray  # (rows, p, p)
    b: np.ndarray  # (rows, p)
    c: np.ndarray  # (rows,)
    y_min: np.ndarray = field(default=None)  # type: ignore[assignment]
    y_max: np.ndarray = field(default=None)  # type: ignore[assignment]
    y_sum: np.ndarray = field(default=None)  # type: ignore[assignment]
    n_samples: int = 0
    #: the equations the structure left out of the fit (:meth:`~.terms.ModelStructure.fit_mask`), kept
    #: apart when the structure asks for them (``track_left_out``, e.g. to score a law on every sample)
    left_out: "NormalEquations | None" = None

    @classmethod
    def zeros(cls, rows: int, p: int, left_out: bool = False) -> "NormalEquations":
        return cls(
            np.zeros((rows, p, p)), np.zeros((rows, p)), np.zeros(rows),
            np.full(rows, np.inf), np.full(rows, -np.inf), np.zeros(rows), 0,
            cls.zeros(rows, p) if left_out else None,
        )

    def add(self, W: np.ndarray, y: np.ndarray) -> None:
        """Fold a chunk: W (n, rows, p), y (n, rows)."""
        Wt = np.ascontiguousarray(W.transpose(1, 0, 2))  # (rows, n, p)
        self.A += np.matmul(Wt.transpose(0, 2, 1), Wt)
        self.b += np.einsum("rnp,nr->rp", Wt, y)
        self._stats(y)

    def add_blocks(self, Wb: np.ndarray, F: np.ndarray, act_rows: np.ndarray, y: np.ndarray,
                   body_columns: list[tuple[int, int]] | None = None, *, upper_only: bool = False,
                   y_stats: np.ndarray | None = None) -> None:
        """Fold a chunk given as blocks: body regressor Wb (n, rows, nb), joint features
        F (n, n_act, nt) that sit on row ``act_rows[k]`` in columns nb + k·nt … (k+1)·nt.

        Equivalent to :meth:`add` on the assembled regressor. Per row r only the body columns
        ``body_columns[r] = (c0, c1)`` (the others must be zero; default: all) and that row's joint
        terms are folded, as three products on strided views of Wb and F (no copies): the body block
        MᵀM (NumPy calls BLAS SYRK for ``M.T @ M``), the cross block MᵀF_r and F_rᵀF_r.
        ``upper_only`` skips the lower cross block, left to one :meth:`mirror_upper` after the last
        chunk (what :func:`compress` does); otherwise A stays symmetric. ``y_stats``: the targets for
        the range statistics, when ``y`` has rows left out of the fit (zeroed).
        """
        n, rows, nb = Wb.shape
        nt = F.shape[2]
        term_of_row = {int(r): k for k, r in enumerate(act_rows)}
        for r in range(rows):
            c0, c1 = body_columns[r] if body_columns is not None else (0, nb)
            M, yr, Ar = Wb[:, r, c0:c1], y[:, r], self.A[r]
            if c1 > c0:
                Ar[c0:c1, c0:c1] += M.T @ M
                self.b[r, c0:c1] += yr @ M
            k = term_of_row.get(r)
            if k is None or nt == 0:
                continue
            t = slice(nb + k * nt, nb + (k + 1) * nt)
            Fk = F[:, k, :]
            Ar[t, t] += Fk.T @ Fk
            self.b[r, t] += yr @ Fk
            if c1 > c0:
                cross = M.T @ Fk
                Ar[c0:c1, t] += cross
                if not upper_only:
                    Ar[t, c0:c1] += cross.T
        self._stats(y, y_stats)

    def mirror_upper(self) -> None:
        """Complete each A_r from its upper triangle (after folds with ``upper_only``)."""
        self.A[:] = np.triu(self.A) + np.swapaxes(np.triu(self.A, 1), -1, -2)  # every row at once: _mirror's sums
        if self.left_out is not None:
            self.left_out.mirror_upper()

    def add_pooled(self, Z: np.ndarray, z: np.ndarray, y_rows: np.ndarray) -> None:
        """Fold equations whose rows are not kept apart: Z (m, p), z (m,) add ZᵀZ, Zᵀz and ‖z‖²
        spread equally over the R rows (A_r += ZᵀZ / R, …), so every total is exact and each row
        carries the pooled mean. ``y_rows`` (n, R) feeds the per-row range statistics and the
        sample count. Used by the contact null-space fold (:class:`~.contact.ContactStructure`)."""
        R = self.A.shape[0]
        self.A += syrk_fold(Z) / R
        self.b += (Z.T @ z) / R
        self.c += float(z @ z) / R
        self.y_min = np.minimum(self.y_min, y_rows.min(axis=0))
        self.y_max = np.maximum(self.y_max, y_rows.max(axis=0))
        self.y_sum += y_rows.sum(axis=0)
        self.n_samples += y_rows.shape[0]

    def _stats(self, y: np.ndarray, y_stats: np.ndarray | None = None) -> None:
        """c from the fitted targets ``y``; range, sum and count from ``y_stats`` (default ``y``)."""
        self.c += np.einsum("nr,nr->r", y, y)
        y = y if y_stats is None else y_stats
        self.y_min = np.minimum(self.y_min, y.min(axis=0))
        self.y_max = np.maximum(self.y_max, y.max(axis=0))
        self.y_sum += y.sum(axis=0)
        self.n_samples += y.shape[0]

    def merge(self, other: "NormalEquations") -> "NormalEquations":
        both = self.left_out is not None and other.left_out is not None
        return NormalEquations(
            self.A + other.A, self.b + other.b, self.c + other.c,
            np.minimum(self.y_min, other.y_min), np.maximum(self.y_max, other.y_max),
            self.y_sum + other.y_sum, self.n_samples + other.n_samples,
            self.left_out.merge(other.left_out) if both else None,
        )

    @classmethod
    def sum(cls, parts: "list[NormalEquations]", left_out: bool = True) -> "NormalEquations":
        """The equations of ``parts`` together (:meth:`merge` over the list, accumulated in place: one copy);
        without their ``left_out`` equations unless ``left_out``."""
        first = parts[0]
        keep = left_out and all(p.left_out is not None for p in parts)
        out = cls(first.A.copy(), first.b.copy(), first.c.copy(), first.y_min.copy(), first.y_max.copy(),
                  first.y_sum.copy(), first.n_samples, cls.sum([p.left_out for p in parts]) if keep else None)
        for p in parts[1:]:
            out.A += p.A
            out.b += p.b
            out.c += p.c
            np.minimum(out.y_min, p.y_min, out=out.y_min)
            np.maximum(out.y_max, p.y_max, out=out.y_max)
            out.y_sum += p.y_sum
            out.n_samples += p.n_samples
        return out

    def total(self, row_weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Summed (A, b, c) with optional per-row weights w_r (= 1/σ_r²)."""
        w = np.ones(self.A.shape[0]) if row_weights is None else np.asarray(row_weights, dtype=float)
        return (
            np.einsum("r,rpq->pq", w, self.A),
            np.einsum("r,rp->p", w, self.b),
            float(w @ self.c),
        )

    def residual_ss(self, params: np.ndarray) -> np.ndarray:
        """Per-row sum of squared residuals ‖W_r π − y_r‖²."""
        quad = np.einsum("p,rpq,q->r", params, self.A, params)
        return np.maximum(quad - 2.0 * self.b @ params + self.c, 0.0)

    def rmse(self, params: np.ndarray) -> np.ndarray:
        return np.sqrt(self.residual_ss(params) / max(self.n_samples, 1))


def iter_trajectories(data: Trajectory | Iterable[Trajectory]) -> Iterator[Trajectory]:
    """Yield trajectories from one trajectory, a list, or a generator of chunks; anything else
    is a :class:`~sensorless.errors.DataError` naming what was given."""
    if isinstance(data, Trajectory):
        yield data
        return
    if not isinstance(data, Iterable) or isinstance(data, (str, bytes, os.PathLike)):
        raise DataError(f"expected a Trajectory or an iterable of them, got {type(data).__name__}")
    for item in data:
        if not isinstance(item, Trajectory):
            raise DataError(f"expected Trajectory items (or file paths), got {type(item).__name__}")
        yield item


def compress_trajectories(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory],
    *,
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
    overlap: bool | None = None,
) -> NormalEquations:
    """Evaluate the regressor chunk by chunk in this process and fold it into :class:`NormalEquations`
    (:func:`~sensorless.regressor.compress.compress` on trajectories; its docstring gives the options).
    """
    return compress_folds(structure, data, None, 1, chunk=chunk, progress=progress, overlap=overlap)[0]


def compress_folds(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory],
    fold_of: "Callable[[int, Trajectory], Callable[[int, int], np.ndarray]] | None",
    n_folds: int,
    *,
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
    overlap: bool | None = None,
    mirror: bool = True,
) -> list[NormalEquations]:
    """:func:`compress_trajectories` with each sample folded into the equations of its fold:
    ``fold_of(k, traj)(start, stop)`` gives the folds (0 … n_folds − 1) of samples [start, stop) of
    the k-th trajectory. One pass: every chunk's regressor is evaluated once, and the masks of the
    fit (rest, reversals) are those of the whole log, so the folds sum to the whole log's equations
    (up to rounding). Structures that fold their own equations (contacts) take ``fold_of=None``.
    ``mirror=False`` leaves each A_r as its upper triangle (the lower cross blocks not added): the caller
    sums folds first and completes the sums with :meth:`NormalEquations.mirror_upper` (mirroring is linear)."""
    track = bool(getattr(structure, "track_left_out", False))
    nes = [NormalEquations.zeros(structure.n_rows, structure.n_params, left_out=track) for _ in range(max(n_folds, 1))]
    row_map = structure.row_map
    own_fold = row_map.per_sample  # a map that changes per sample (contacts): the structure folds its equations
    if own_fold and fold_of is not None:
        raise DataError("equations folded per sample (contacts) cannot be split into folds in one pass")
    # per-row subtree columns only where each kept row is one row of Pinocchio's joint-torque regressor
    # and the block is the bodies alone (a transmission's Gᵀ rows and drive columns couple rows: fold every column)
    dense = not row_map.selects_rows or structure.n_block_params != structure.n_body_params
    cols = structure.row_body_columns() if not (dense or own_fold) else None
    if overlap is None:
        overlap = idle_core()
    seen = False
    with one_blas_thread(), (ThreadPoolExecutor(1) if overlap and not own_fold else _NoPool()) as pool:
        bufs = [np.empty((chunk, structure.n_rows, structure.n_block_params)) for _ in range(2 if pool else 1)]
        pending = [None, None]
        k = 0
        for n_traj, traj in enumerate(iter_trajectories(data)):
            seen = True
            prev_v = None
            folds_in = fold_of(n_traj, traj) if fold_of is not None else None
            # a presliding state depends on the history of q: integrated along this whole log from 0
            states = getattr(structure, "friction_states", None)
            Z = states(traj) if states is not None and not own_fold else None
            for start, part in enumerate(traj.chunks(chunk)):
                start *= chunk
                if own_fold:
                    structure.fold(nes[0], part)
                    if progress is not None:
                        progress(len(part))
                    continue
                slot = k % len(bufs)
                if pending[slot] is not None:  # the fold still reading this buffer
                    pending[slot].result()
                Q, V, A = structure.state(part)
                Wb = structure.block_regressor(Q, V, A, out=bufs[slot])  # [bodies | drive terms]
                F = structure.joint_features(V, A, None if Z is None else Z[start : start + len(part)])
                y = structure.target(part)
                keep = _fit_mask(structure, traj, start, len(part), V, prev_v)
                prev_v = V[-1:]
                folds = None if folds_in is None else np.asarray(folds_in(start, start + len(part)))
                args = (nes, folds, structure, Wb, F, y, keep, cols, track)
                if pool:
                    pending[slot] = pool.submit(fold_chunk, *args)
                else:
                    fold_chunk(*args)
                k += 1
                if progress is not None:
                    progress(len(part))
        for f in pending:
            if f is not None:
                f.result()
    if not seen:
        raise DataError("no trajectory was given")
    if not own_fold and mirror:
        for ne in nes:
            ne.mirror_upper()
    return nes


def fold_chunk(nes: list, folds: "np.ndarray | None", structure, Wb, F, y, keep, cols, track: bool) -> None:
    """A chunk's samples into the equations of their folds (``folds``: per sample, or None: all into
    ``nes[0]``), one contiguous run of a fold at a time (views, no copies: a phase block spans many
    samples). Runs in the helper thread with ``overlap``; chunks are folded in order."""
    if folds is None:
        fold_into(nes[0], structure, Wb, F, y, keep, cols, track)
        return
    edges = np.concatenate([[0], np.flatnonzero(np.diff(folds)) + 1, [len(folds)]])
    for a, b in zip(edges[:-1], edges[1:]):
        fold_into(nes[int(folds[a])], structure, Wb[a:b], F[a:b], y[a:b], None if keep is None else keep[a:b],
                  cols, track)


def fold_into(ne: NormalEquations, structure, Wb, F, y, keep, cols, track: bool) -> None:
    """One chunk (regressor block ``Wb``, joint features ``F``, targets ``y``) into ``ne``: the
    equations left out of the fit (``keep == 0``: at rest, at a reversal) zeroed in place, and folded
    apart into ``ne.left_out`` when tracked (only the samples with such rows)."""
    rows = structure.term_rows
    y_stats = None
    if keep is not None:
        out = keep == 0
        if out.any():
            if track:
                i = np.flatnonzero(out.any(axis=1))
                o = out[i]
                ne.left_out.add_blocks(Wb[i] * o[:, :, None], F[i] * o[:, rows, None], rows, y[i] * o, cols,
                                       upper_only=True)
            y_stats, y = y, y.copy()
            Wb[out], y[out] = 0.0, 0.0  # in place: this chunk's own buffer (or a view of it)
            F[out[:, rows]] = 0.0
    ne.add_blocks(Wb, F, rows, y, cols, upper_only=True, y_stats=y_stats)


def _fit_mask(structure, traj: Trajectory, start: int, n: int, V: np.ndarray, prev_v: "np.ndarray | None"):
    """The structure's fit mask of samples [start, start + n) of ``traj`` (velocities ``V``; ``prev_v``:
    those of the sample before), seen with one neighbour sample on each side (a mask may depend on
    them, e.g. a velocity reversal), so that it does not depend on the chunking."""
    lo, hi = max(start - 1, 0), min(start + n + 1, len(traj))
    if (lo, hi) == (start, start + n):
        return structure.fit_mask(V)
    parts = [prev_v if prev_v is not None else structure.state(traj.take(slice(lo, start)))[1]] if lo < start else []
    parts += [V] + ([structure.state(traj.take(slice(start + n, hi)))[1]] if hi > start + n else [])
    keep = structure.fit_mask(np.concatenate(parts))
    return None if keep is None else keep[start - lo : start - lo + n]


def idle_core() -> bool:
    """True when a second core is free (1-min load average below cores − 1): the overlap thread pays off."""
    cores = os.cpu_count() or 1
    try:
        return cores > 1 and os.getloadavg()[0] < cores - 1
    except OSError:  # pragma: no cover - no load average on this platform
        return cores > 1


class _NoPool:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


class RowMajorFold:
    """:func:`fold_chunk` for chunks laid out row-major, X (rows, n, K): row r's equations of the n samples
    are X[r] (the block columns [bodies | drive terms] 0 … nb, then row r's joint terms nb … K), and only
    the contiguous column range ``ranges[r] = (lo, hi)`` can be non-zero (its subtree's bodies from
    :meth:`~.terms.ModelStructure.row_body_columns`, up to its joint terms). Per fold and row it keeps

        G_r = Σ X_r[:, lo:hi]ᵀ X_r[:, lo:hi],   h_r = Σ X_r[:, lo:hi]ᵀ y_r

    one product per row and run of a fold (``M.T @ M`` on a strided view, which NumPy hands to BLAS SYRK;
    the body–joint-term cross block inside it), and :meth:`equations` scatters them into
    :class:`NormalEquations` (column j < nb of X is parameter j, j ≥ nb the term j − nb of row r's joint,
    ``term_index[r]``, among ``n_terms`` per joint). Equal to :func:`fold_chunk` on the (n, rows, ·)
    blocks to rounding; a regressor kernel and the joint features write X in place (no copies), and the
    row-major views make the products about 20 % faster."""

    def __init__(self, n_folds: int, ranges: list[tuple[int, int]], term_index: list["int | None"], nb: int,
                 n_terms: int, n_params: int, track_left_out: bool = False):
        self.ranges, self.term_index, self.nb, self.n_terms, self.n_params = ranges, term_index, nb, n_terms, n_params
        rows = len(ranges)
        self.nes = [NormalEquations.zeros(rows, 0, left_out=track_left_out) for _ in range(max(n_folds, 1))]
        self.G = [[np.zeros((hi - lo, hi - lo)) for lo, hi in ranges] for _ in self.nes]
        self.h = [[np.zeros(hi - lo) for lo, hi in ranges] for _ in self.nes]
        self.G_out = [[np.zeros((hi - lo, hi - lo)) for lo, hi in ranges] for _ in self.nes] if track_left_out else None
        self.h_out = [[np.zeros(hi - lo) for lo, hi in ranges] for _ in self.nes] if track_left_out else None

    def add(self, X: np.ndarray, y: np.ndarray, keep: "np.ndarray | None", folds: "np.ndarray | None") -> None:
        """One chunk: X (rows, n, K) (zeroed in place where ``keep == 0``: the equations left out of the fit,
        folded apart when tracked), targets y (n, rows), ``folds`` per sample (None: all in fold 0)."""
        y_stats = None
        if keep is not None:
            out = keep == 0
            if out.any():
                if self.G_out is not None:
                    i = np.flatnonzero(out.any(axis=1))
                    o = out[i].T
                    self._add_runs(X[:, i] * o[:, :, None], y[i] * o.T, None if folds is None else folds[i],
                                   self.G_out, self.h_out, lambda f: self.nes[f].left_out, None)
                y_stats, y = y, y.copy()
                X.transpose(1, 0, 2)[out] = 0.0
                y[out] = 0.0
        self._add_runs(X, y, folds, self.G, self.h, lambda f: self.nes[f], y_stats)

    def _add_runs(self, X, y, folds, G, h, ne_of, y_stats) -> None:
        n = X.shape[1]
        if folds is None:
            edges, fold_at = [0, n], [0]
        else:
            edges = np.concatenate([[0], np.flatnonzero(np.diff(folds)) + 1, [n]])
            fold_at = [int(folds[a]) for a in edges[:-1]]
        for f, a, b in zip(fold_at, edges[:-1], edges[1:]):
            for r, (lo, hi) in enumerate(self.ranges):
                M = X[r, a:b, lo:hi]
                G[f][r] += M.T @ M
                h[f][r] += y[a:b, r] @ M
            ne_of(f)._stats(y[a:b], None if y_stats is None else y_stats[a:b])

    def _columns(self, r: int) -> np.ndarray:
        lo, hi = self.ranges[r]
        j = np.arange(lo, hi)
        k = self.term_index[r]
        return np.where(j < self.nb, j, self.nb + (0 if k is None else k) * self.n_terms + (j - self.nb))

    def equations(self) -> list[NormalEquations]:
        """The folds' :class:`NormalEquations` (``left_out`` too when tracked)."""
        rows, p = len(self.ranges), self.n_params

        def build(ne, G, h):
            A, b = np.zeros((rows, p, p)), np.zeros((rows, p))
            for r in range(rows):
                idx = self._columns(r)
                A[r][np.ix_(idx, idx)] = G[r]
                b[r, idx] = h[r]
            return NormalEquations(A, b, ne.c, ne.y_min, ne.y_max, ne.y_sum, ne.n_samples)

        out = []
        for f, ne in enumerate(self.nes):
            res = build(ne, self.G[f], self.h[f])
            if self.G_out is not None:
                res.left_out = build(ne.left_out, self.G_out[f], self.h_out[f])
            out.append(res)
        return out

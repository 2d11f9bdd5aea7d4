"""Streaming compression of the identification equations.

Stacking W π ≈ y over N samples would need N · rows · p floats. Instead each chunk of
samples is folded into per-row normal equations

    A_r = Σ_i W_{i,r}ᵀ W_{i,r},   b_r = Σ_i W_{i,r}ᵀ y_{i,r},   c_r = Σ_i y_{i,r}²

one set per equation row r (per joint). Memory is O(rows · p²), independent of N.
Keeping rows separate lets weighted least squares rescale rows afterwards
(A = Σ_r A_r / σ_r²) and gives per-joint residuals ‖W_r π − y_r‖² = πᵀA_rπ − 2πᵀb_r + c_r
without a second pass over the data. Range statistics of y are kept for NRMSE.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Iterator

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError
from .terms import ModelStructure

__all__ = ["NormalEquations", "compress", "iter_trajectories"]


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

    @classmethod
    def zeros(cls, rows: int, p: int) -> "NormalEquations":
        return cls(
            np.zeros((rows, p, p)), np.zeros((rows, p)), np.zeros(rows),
            np.full(rows, np.inf), np.full(rows, -np.inf), np.zeros(rows), 0,
        )

    def add(self, W: np.ndarray, y: np.ndarray) -> None:
        """Fold a chunk: W (n, rows, p), y (n, rows)."""
        Wt = np.ascontiguousarray(W.transpose(1, 0, 2))  # (rows, n, p)
        self.A += np.matmul(Wt.transpose(0, 2, 1), Wt)
        self.b += np.einsum("rnp,nr->rp", Wt, y)
        self._stats(y)

    def add_blocks(self, Wb: np.ndarray, F: np.ndarray, act_rows: np.ndarray, y: np.ndarray) -> None:
        """Fold a chunk given as blocks: body regressor Wb (n, rows, nb), joint features
        F (n, n_act, nt) that sit on row ``act_rows[k]`` in columns nb + k·nt … (k+1)·nt.

        Equivalent to :meth:`add` on the assembled regressor, but exploits the sparsity of
        the joint-term columns (one joint per row) and reads Wb without transposing it.
        """
        nb = Wb.shape[2]
        nt = F.shape[2]
        for r in range(Wb.shape[1]):
            Wr = Wb[:, r, :]  # strided view, BLAS-compatible
            self.A[r, :nb, :nb] += Wr.T @ Wr
            self.b[r, :nb] += Wr.T @ y[:, r]
        for k, r in enumerate(act_rows):
            c = slice(nb + k * nt, nb + (k + 1) * nt)
            Fk = F[:, k, :]
            cross = Wb[:, r, :].T @ Fk
            self.A[r, :nb, c] += cross
            self.A[r, c, :nb] += cross.T
            self.A[r, c, c] += Fk.T @ Fk
            self.b[r, c] += Fk.T @ y[:, r]
        self._stats(y)

    def _stats(self, y: np.ndarray) -> None:
        self.c += np.einsum("nr,nr->r", y, y)
        self.y_min = np.minimum(self.y_min, y.min(axis=0))
        self.y_max = np.maximum(self.y_max, y.max(axis=0))
        self.y_sum += y.sum(axis=0)
        self.n_samples += y.shape[0]

    def merge(self, other: "NormalEquations") -> "NormalEquations":
        return NormalEquations(
            self.A + other.A, self.b + other.b, self.c + other.c,
            np.minimum(self.y_min, other.y_min), np.maximum(self.y_max, other.y_max),
            self.y_sum + other.y_sum, self.n_samples + other.n_samples,
        )

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
    """Yield trajectories from one trajectory, a list, or a generator of chunks."""
    if isinstance(data, Trajectory):
        yield data
        return
    yield from data


def compress(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory],
    *,
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
    client=None,
    reader=None,
) -> NormalEquations:
    """Evaluate the regressor chunk by chunk and fold it into :class:`NormalEquations`.

    ``data`` may be a generator, so arbitrarily long logs never sit in memory whole.
    ``progress(n)`` is called with the number of samples folded after each chunk.

    With a Dask ``client`` (``distributed.Client``), ``data`` are file paths or glob patterns:
    each worker reads and preprocesses its own files (``reader``, default
    :class:`~.distributed.LogReader`) and returns partial sums, added by a tree reduction
    (:func:`~.distributed.compress_files`; ``progress(1)`` per finished file). A file that
    cannot be used raises its typed error; to skip such files instead, use ``compress_files``.
    """
    if client is not None:
        from .distributed import compress_files

        return compress_files(structure, data, client=client, reader=reader, chunk=chunk, progress=progress).equations
    ne = NormalEquations.zeros(structure.n_rows, structure.n_params)
    buf = np.empty((chunk, structure.n_rows, structure.n_body_params))
    seen = False
    for traj in iter_trajectories(data):
        seen = True
        for part in traj.chunks(chunk):
            if hasattr(structure, "fold"):  # structures with their own row map (e.g. contacts)
                structure.fold(ne, part)
                if progress is not None:
                    progress(len(part))
                continue
            Q, V, A = structure.state(part)
            Wb = structure.body_regressor(Q, V, A, out=buf)
            F, y = structure.joint_features(V, A), structure.target(part)
            keep = structure.fit_mask(V) if hasattr(structure, "fit_mask") else None
            if keep is not None:  # equations left out of the fit (a joint at rest): zero rows
                Wb, F, y = Wb * keep[:, :, None], F * keep[:, structure.actuated_rows, None], y * keep
            ne.add_blocks(Wb, F, structure.actuated_rows, y)
            if progress is not None:
                progress(len(part))
    if not seen:
        raise DataError("no trajectory was given")
    return ne

"""Row maps: the linear map M applied to both sides of the equations of motion.

Every identification model here is one equation with one row per tree velocity (nv rows),

    Y(q, v, v̇) π + Sᵀ Φ φ = Sᵀ τ   (+ Jcᵀ f),

multiplied on the left by a row map M that picks or combines rows:

* :class:`ActuatedRows`: M = a row selection (the actuated joints' rows of a fixed-base arm,
  ``rows="actuated"``; all nv rows, ``rows="all"``).
* :class:`TransmissionRows`: M = Gᵀ for joints q = Gθ + q₀ (coupled joints, parallelograms):
  by virtual work τ_θ = Gᵀ τ_q. Constant, n_coordinates × n_tree_joints.
* :class:`ContactNullSpace`: M = P(q) = I − Jc⁺Jc per sample (P Jcᵀ = 0 removes the unknown
  contact wrenches); with measured wrenches (``mode="wrench"``) M is a row selection and
  Jcᵀ f moves to the known side. Depends on the state and the contact flags.

A structure (:class:`~.terms.ModelStructure` and its subclasses) exposes its map as
``structure.row_map``; :func:`~.compress.compress` reads ``selects_rows`` (row r of M Y is
one row of Y, so Pinocchio's per-row subtree column blocks apply) and ``per_sample`` (M
changes per sample: the structure folds its own mapped equations, ``structure.fold``).
Callers ask the map, not the structure's type, what the equations are: ``projected`` (M is
the state-dependent projector P(q)) and ``measured_wrench`` (measured contact wrenches are
on the known side); both are False for the constant maps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from ..errors import DataError

__all__ = ["ActuatedRows", "ContactNullSpace", "RowMap", "TransmissionRows"]


@runtime_checkable
class RowMap(Protocol):
    """M: (N, nv, …) full-equation rows → (N, n_rows, …) kept equations."""

    selects_rows: bool
    per_sample: bool
    projected: bool
    measured_wrench: bool

    @property
    def n_rows(self) -> int: ...

    @property
    def row_names(self) -> list[str]: ...

    def apply(self, X: np.ndarray, Q: np.ndarray | None = None, flags: np.ndarray | None = None) -> np.ndarray:
        """M X for X of shape (N, nv) or (N, nv, p) (``Q``, ``flags``: the state, for maps that need it)."""
        ...


def _rows_first(M: np.ndarray, X: np.ndarray) -> np.ndarray:
    """M X for a constant M (r, nv) and X (N, nv, …)."""
    return np.einsum("rj,nj...->nr...", M, X, optimize=True)


class _NamedRows:
    """A constant map with named rows (``names``, one per kept row)."""

    names: tuple[str, ...]
    per_sample = False
    projected = False
    measured_wrench = False

    @property
    def n_rows(self) -> int:
        return len(self.names)

    @property
    def row_names(self) -> list[str]:
        return list(self.names)


@dataclass(frozen=True)
class ActuatedRows(_NamedRows):
    """Row selection: kept row r is row ``index[r]`` of the full equation (Sᵀ rows or all rows)."""

    index: np.ndarray
    names: tuple[str, ...]
    selects_rows = True

    def matrix(self, nv: int) -> np.ndarray:
        """The selection as a 0/1 matrix (n_rows, nv)."""
        M = np.zeros((self.n_rows, nv))
        M[np.arange(self.n_rows), self.index] = 1.0
        return M

    def apply(self, X, Q=None, flags=None):
        return np.asarray(X)[:, self.index]


@dataclass(frozen=True)
class TransmissionRows(_NamedRows):
    """M = Gᵀ restricted to the kept coordinates: ``GT`` (n_rows, n_tree_joints)."""

    GT: np.ndarray
    names: tuple[str, ...]
    selects_rows = False

    @classmethod
    def from_coupling(cls, G: np.ndarray, rows: Sequence[int], coordinates: Sequence[str]) -> "TransmissionRows":
        rows = np.asarray(rows, dtype=int)
        return cls(np.ascontiguousarray(np.asarray(G, float)[:, rows].T), tuple(coordinates[i] for i in rows))

    def apply(self, X, Q=None, flags=None):
        return _rows_first(self.GT, np.asarray(X))


class ContactNullSpace:
    """M = P(q) = I − Jc⁺Jc of the active contacts (``mode="projected"``), or the row selection
    of the kept rows when the wrenches are measured (``mode="wrench"``); ``structure`` is a
    :class:`~.contact.ContactStructure` (its Jacobians and projector)."""

    selects_rows = False
    per_sample = True

    def __init__(self, structure) -> None:
        self.structure = structure

    @property
    def projected(self) -> bool:
        return self.structure.mode == "projected"

    @property
    def measured_wrench(self) -> bool:
        return self.structure.mode == "wrench"

    @property
    def n_rows(self) -> int:
        return len(self.structure._row_idx)

    @property
    def row_names(self) -> list[str]:
        return self.structure.row_names

    def apply(self, X, Q=None, flags=None):
        X = np.asarray(X)
        if not self.projected:
            return X[:, self.structure._row_idx]
        if Q is None or flags is None:
            raise DataError("the contact null-space map needs the configurations Q and the contact flags")
        P = self.structure.projector(Q, flags)
        return np.matmul(P, X) if X.ndim == 3 else np.einsum("nij,nj->ni", P, X)

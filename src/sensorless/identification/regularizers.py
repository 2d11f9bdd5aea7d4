"""Regularisers pulling the identified parameters toward a prior π0 (e.g. the CAD model).

All are dimensionless and evaluated on the scaled variable of an
:class:`~.constraints.LmiContext` (``Ĵ_k = T_k⁻¹ J_k T_k⁻¹``, see :mod:`.constraints`):

* :class:`Euclidean` — ``Σ_k ‖x_k − x0_k‖²``: squared distance in the per-body
  mass/length-scaled coordinates (plain ``‖π − π0‖²`` would mix kg, kg·m and kg·m²);
* :class:`ConstantPullback` — the affine-invariant Riemannian metric of the cone of
  pseudo-inertias frozen at the prior (Lee, Wensing & Park 2020)::

      d²(J, J0) ≈ ½ tr((J0⁻¹ ΔJ)²) = ½ ‖J0^{-1/2} ΔJ J0^{-1/2}‖²_F,   ΔJ = Σ_i Δπ_i A_i

  a quadratic form ``Δπᵀ M Δπ`` that is fed to the solver as ``‖F Δπ‖²`` with ``F`` the
  Cholesky (QR) factor of ``M``;
* :class:`Entropic` — the log-det Bregman divergence (relative entropy of the Gaussian
  densities with second moments J, J0)::

      D(J ‖ J0) = −log det(J0⁻¹ J) + tr(J0⁻¹ J) − 4

  whose second-order expansion is the pullback metric above (so both share a scale of
  γ); it keeps every body strictly inside the cone (``log_det``: exponential + PSD cones).

The two geometric metrics are invariant to the scaling (``J ↦ T J T``). A singular or
zero-mass prior body is regularised as ``Ĵ0 + δ I`` (``δ`` in the body's scaled units,
in which a normal body has ``tr Ĵ0 = 2``). Joint terms (friction, offset, armature)
have no geometry; every regulariser adds ``joint_weight · ‖x_j − x0_j‖²`` on their
(data-scaled) coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cvxpy as cp
import numpy as np
import scipy.sparse as sp

from ..parameters import as_bodies, pseudo_inertia, pseudo_inertia_basis
from .constraints import LmiContext

__all__ = [
    "REGULARIZERS",
    "ConstantPullback",
    "Entropic",
    "Euclidean",
    "Regularizer",
    "entropic_divergence",
    "make_regularizer",
    "pullback_distance",
    "pullback_matrix",
]

_BASIS = pseudo_inertia_basis()  # (10, 4, 4)


class Regularizer(Protocol):
    name: str

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression: ...


def eigenvalue_floor(J0: np.ndarray, delta: float) -> np.ndarray:
    """The symmetric part of ``J0`` with its eigenvalues raised to at least ``delta``: V max(λ, δ) Vᵀ."""
    lam, V = np.linalg.eigh(0.5 * (J0 + J0.T))
    return (V * np.maximum(lam, delta)) @ V.T


def pullback_matrix(J0: np.ndarray) -> np.ndarray:
    """``M`` (10×10) with ``Δπᵀ M Δπ = ½ tr((J0⁻¹ ΔJ)²)``; ``J0`` positive definite."""
    lam, V = np.linalg.eigh(J0)
    L = (V / np.sqrt(lam)) @ V.T  # J0^{-1/2}
    G = np.einsum("ab,ibc,cd->iad", L, _BASIS, L).reshape(10, 16).T
    return 0.5 * G.T @ G


def _pullback_factor(J0: np.ndarray) -> np.ndarray:
    """Upper-triangular ``F`` with ``FᵀF = pullback_matrix(J0)``."""
    lam, V = np.linalg.eigh(J0)
    L = (V / np.sqrt(lam)) @ V.T
    G = np.einsum("ab,ibc,cd->iad", L, _BASIS, L).reshape(10, 16).T / np.sqrt(2.0)
    return np.linalg.qr(G, mode="r")


def pullback_distance(pi: np.ndarray, pi0: np.ndarray) -> float:
    """``Σ_k ½ tr((J0_k⁻¹ (J_k − J0_k))²)`` over the bodies of stacked vectors (``J0_k ≻ 0``)."""
    J, J0 = pseudo_inertia(as_bodies(pi)), pseudo_inertia(as_bodies(pi0))
    X = np.linalg.solve(J0, J - J0)
    return float(0.5 * np.einsum("kab,kba->", X, X))


def entropic_divergence(pi: np.ndarray, pi0: np.ndarray) -> float:
    """``Σ_k −log det(J0_k⁻¹ J_k) + tr(J0_k⁻¹ J_k) − 4`` (``J_k, J0_k ≻ 0``; inf otherwise)."""
    J, J0 = pseudo_inertia(as_bodies(pi)), pseudo_inertia(as_bodies(pi0))
    X = np.linalg.solve(J0, J)
    sign, logdet = np.linalg.slogdet(X)
    if np.any(sign <= 0):
        return float("inf")
    return float(np.sum(-logdet + np.trace(X, axis1=-2, axis2=-1) - 4.0))


def _joint_term(x: cp.Variable, ctx: LmiContext, weight: float) -> cp.Expression | float:
    js = ctx.joint_slice()
    if weight <= 0 or js.stop == js.start:
        return 0.0
    return weight * cp.sum_squares(x[js] - ctx.x0[js])


@dataclass
class Euclidean:
    """``Σ_k ‖x_k − x0_k‖² + joint_weight ‖x_j − x0_j‖²`` (scaled coordinates)."""

    joint_weight: float = 1.0
    name: str = "euclidean"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        nb = ctx.structure.n_body_params
        return cp.sum_squares(x[:nb] - ctx.x0[:nb]) + _joint_term(x, ctx, self.joint_weight)


@dataclass
class ConstantPullback:
    """``Σ_k ½ tr((Ĵ0_k⁻¹ ΔĴ_k)²) + joint_weight ‖x_j − x0_j‖²`` with ``Ĵ0_k`` clipped at ``δ``."""

    delta: float = 1e-3
    joint_weight: float = 1.0
    name: str = "pullback"

    def factor(self, ctx: LmiContext) -> sp.csr_matrix:
        """Block-diagonal ``F`` (10 n × 10 n) with ``‖F (x − x0)‖²`` = the body part."""
        blocks = [_pullback_factor(eigenvalue_floor(ctx.scaled_prior_pseudo_inertia(k), self.delta)) for k in range(ctx.n_bodies)]
        return sp.block_diag(blocks, format="csr")

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        nb = ctx.structure.n_body_params
        return cp.sum_squares(self.factor(ctx) @ (x[:nb] - ctx.x0[:nb])) + _joint_term(x, ctx, self.joint_weight)


@dataclass
class Entropic:
    """``Σ_k −log det Ĵ_k + tr(Ĵ0_k⁻¹ Ĵ_k) + log det Ĵ0_k − 4 + joint_weight ‖x_j − x0_j‖²``."""

    delta: float = 1e-3
    joint_weight: float = 1.0
    name: str = "entropic"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        terms = []
        const = 0.0
        lin = np.zeros(ctx.structure.n_body_params)
        for k in range(ctx.n_bodies):
            J0 = eigenvalue_floor(ctx.scaled_prior_pseudo_inertia(k), self.delta)
            lin[ctx.body_slice(k)] = np.einsum("iab,ab->i", _BASIS, np.linalg.inv(J0))  # tr(J0⁻¹ A_i)
            const += np.linalg.slogdet(J0)[1] - 4.0
            terms.append(-cp.log_det(ctx.scaled_pseudo_inertia(x, k)))
        nb = ctx.structure.n_body_params
        return cp.sum(cp.hstack(terms)) + lin @ x[:nb] + const + _joint_term(x, ctx, self.joint_weight)


REGULARIZERS = {"euclidean": Euclidean, "pullback": ConstantPullback, "entropic": Entropic}


def make_regularizer(spec: str | Regularizer | None, **kwargs) -> Regularizer | None:
    """A regulariser from its name ("pullback", "entropic", "euclidean"), an instance, or None."""
    if spec is None or not isinstance(spec, str):
        return spec
    try:
        return REGULARIZERS[spec](**kwargs)
    except KeyError:
        raise ValueError(f"unknown regularization '{spec}'; choose from {sorted(REGULARIZERS)} or None") from None

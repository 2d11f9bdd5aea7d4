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
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..parameters import as_bodies, pseudo_inertia, pseudo_inertia_basis
from .constraints import LmiContext

if TYPE_CHECKING:
    import cvxpy as cp
    import scipy.sparse as sp

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
    """``reg(x, ctx)``: the regulariser as a cvxpy expression of the scaled variable. A quadratic
    one also has ``metric(ctx)``: ``G`` (p × p) with value ``(x − x0)ᵀ G (x − x0)``, which lets
    :mod:`.lmi` skip cvxpy and :mod:`.unconstrained` solve in closed form."""

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
    import cvxpy as cp

    js = ctx.joint_slice()
    if weight <= 0 or js.stop == js.start:
        return 0.0
    return weight * cp.sum_squares(x[js] - ctx.x0[js])


def _metric(ctx: LmiContext, body_block: np.ndarray, joint_weight: float) -> np.ndarray:
    """``G`` (p × p): ``body_block`` on the body parameters, ``joint_weight · I`` on the joint terms."""
    p, nb = len(ctx.scale), ctx.structure.n_body_params
    G = np.zeros((p, p))
    G[:nb, :nb] = body_block
    js = ctx.joint_slice()
    if joint_weight > 0 and js.stop > js.start:
        G[js, js] += joint_weight * np.eye(js.stop - js.start)
    return G


@dataclass
class Euclidean:
    """``Σ_k ‖x_k − x0_k‖² + joint_weight ‖x_j − x0_j‖²`` (scaled coordinates)."""

    joint_weight: float = 1.0
    name: str = "euclidean"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        import cvxpy as cp

        nb = ctx.structure.n_body_params
        return cp.sum_squares(x[:nb] - ctx.x0[:nb]) + _joint_term(x, ctx, self.joint_weight)

    def metric(self, ctx: LmiContext) -> np.ndarray:
        return _metric(ctx, np.eye(ctx.structure.n_body_params), self.joint_weight)


@dataclass
class ConstantPullback:
    """``Σ_k ½ tr((Ĵ0_k⁻¹ ΔĴ_k)²) + joint_weight ‖x_j − x0_j‖²`` with ``Ĵ0_k`` clipped at ``δ``."""

    delta: float = 1e-3
    joint_weight: float = 1.0
    name: str = "pullback"

    def _blocks(self, ctx: LmiContext) -> list[np.ndarray]:
        return [_pullback_factor(eigenvalue_floor(ctx.scaled_prior_pseudo_inertia(k), self.delta))
                for k in range(ctx.n_bodies)]

    def factor(self, ctx: LmiContext) -> sp.csr_matrix:
        """Block-diagonal ``F`` (10 n × 10 n) with ``‖F (x − x0)‖²`` = the body part."""
        import scipy.sparse as sp

        return sp.block_diag(self._blocks(ctx), format="csr")

    def metric(self, ctx: LmiContext) -> np.ndarray:
        nb = ctx.structure.n_body_params
        M = np.zeros((nb, nb))
        for k, F in enumerate(self._blocks(ctx)):
            M[ctx.body_slice(k), ctx.body_slice(k)] = F.T @ F
        return _metric(ctx, M, self.joint_weight)

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        import cvxpy as cp

        nb = ctx.structure.n_body_params
        return cp.sum_squares(self.factor(ctx) @ (x[:nb] - ctx.x0[:nb])) + _joint_term(x, ctx, self.joint_weight)


@dataclass
class Entropic:
    """``Σ_k −log det Ĵ_k + tr(Ĵ0_k⁻¹ Ĵ_k) + log det Ĵ0_k − 4 + joint_weight ‖x_j − x0_j‖²``."""

    delta: float = 1e-3
    joint_weight: float = 1.0
    name: str = "entropic"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> cp.Expression:
        import cvxpy as cp

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

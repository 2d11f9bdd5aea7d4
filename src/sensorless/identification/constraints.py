"""Composable convex constraints for physically consistent identification.

Every builder is a small callable ``builder(x, ctx) -> list[cvxpy.Constraint]`` on the
*scaled* decision variable ``x`` of an :class:`LmiContext`, with a ``name`` and a
``hint`` (what to relax when the problem is infeasible). The builders here also give the same
constraints as conic rows, ``builder.conic(ctx) -> list[ConicRows]`` (``A x + s = b``, ``s`` in a
cone), which :mod:`.lmi` hands to Clarabel without cvxpy; a builder without ``conic`` sends the
program through cvxpy.

Scaling. The solver works on ``x`` with ``π = scale ⊙ x``. Body ``k`` is scaled by a
mass ``m_k`` and a length ``ℓ_k`` (prior mass and radius of gyration about the joint
origin): ``π_k = diag(m, mℓ, mℓ, mℓ, mℓ², …, mℓ²) x_k``, which is a congruence of the
pseudo-inertia, ``J_k = T_k Ĵ_k T_k`` with ``T_k = √m_k diag(ℓ_k, ℓ_k, ℓ_k, 1)`` and
``Ĵ_k = pseudo_inertia(x_k)``. So ``J_k ⪰ 0 ⇔ Ĵ_k ⪰ 0`` and the conic solver sees
O(1) numbers on every body, from a 0.04 kg foot to a 17 kg torso. Joint terms are
scaled by the data (see :mod:`.lmi`).

Constraints (``Ĵ`` scaled, ``J`` physical):

* :class:`PseudoInertiaPSD` — ``Ĵ_k ⪰ ε I`` (``ε`` relative to the body's scale);
  ``J_k ⪰ 0`` iff some non-negative density produces the body;
* :class:`DensityRealizable` — ``tr(J_k Q_k) ≥ 0`` with ``Q_k`` of the body's bounding
  ellipsoid (:mod:`.ellipsoids`): together with ``J_k ⪰ 0``, the mass can sit inside it;
* :class:`ComInEllipsoid` — ``‖Σ_E^{-1/2}(h − m c_E)‖ ≤ m``: the CoM lies in the
  ellipsoid (implied by the previous one, weaker on its own);
* :class:`NonNegativeFriction` (``fv, fc ≥ 0``), :class:`NonNegativeArmature`;
* :class:`BodyMassBounds`, :class:`TotalMass` (equality or bounds).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterator, Mapping, Protocol, Sequence

import numpy as np

from ..errors import RobotModelError, setting
from ..parameters import as_bodies, pseudo_inertia, pseudo_inertia_basis
from ..regressor.joint_terms import terms_where
from ..regressor.terms import ModelStructure
from .ellipsoids import BoundingEllipsoid
from .prior_projection import svec

if TYPE_CHECKING:
    import cvxpy as cp

__all__ = [
    "BodyMassBounds",
    "ComInEllipsoid",
    "ConicRows",
    "ConstraintBuilder",
    "DensityRealizable",
    "LmiContext",
    "NonNegativeArmature",
    "NonNegativeFriction",
    "PseudoInertiaPSD",
    "TotalMass",
    "constraint_violation",
    "default_constraints",
]

_BASIS16 = pseudo_inertia_basis().reshape(10, 16).T  # vec(J) = _BASIS16 @ pi
_SVEC_BASIS = svec(pseudo_inertia_basis()).T  # svec(Ĵ_k) = _SVEC_BASIS @ x_k (Clarabel's packing)
CONE_KINDS = ("zero", "nonneg", "soc", "psd")


@dataclass(frozen=True)
class ConicRows:
    """Constraints as rows of ``A x + s = b`` with ``s`` in one cone of ``kind``: "zero"
    (equalities), "nonneg", "soc" (``s = (t, u)``, ``‖u‖ ≤ t``; ``dim`` rows) or "psd" (``s`` the
    svec of a ``dim × dim`` symmetric matrix, packed as Clarabel's ``PSDTriangleConeT``)."""

    kind: str
    A: np.ndarray  # (rows, p)
    b: np.ndarray  # (rows,)
    dim: int = 0

    def __post_init__(self) -> None:
        if self.kind not in CONE_KINDS:
            raise ValueError(f"unknown cone {self.kind!r}; choose from {CONE_KINDS}")


def _select_rows(idx: np.ndarray, p: int, sign: float = -1.0) -> np.ndarray:
    """Rows ``sign · e_i`` for ``i`` in ``idx``."""
    A = np.zeros((len(idx), p))
    A[np.arange(len(idx)), idx] = sign
    return A


@dataclass
class LmiContext:
    """What constraint and regulariser builders need: structure, prior, scaling, ellipsoids.

    ``scale`` (p,) maps the decision variable to standard parameters, ``π = scale ⊙ x``.
    Build it with :meth:`create`.
    """

    structure: ModelStructure
    prior: np.ndarray
    scale: np.ndarray
    body_mass: np.ndarray  # (n_bodies,) mass scale m_k
    body_length: np.ndarray  # (n_bodies,) length scale ℓ_k
    ellipsoids: dict[str, BoundingEllipsoid] = field(default_factory=dict)

    @classmethod
    def create(
        cls,
        structure: ModelStructure,
        prior: np.ndarray | None = None,
        ellipsoids: Mapping[str, BoundingEllipsoid] | None = None,
        joint_scale: np.ndarray | None = None,
    ) -> LmiContext:
        """Body scales from the prior (fallbacks for massless or point-like prior bodies);
        ``joint_scale`` (one per joint-term column) defaults to 1."""
        prior = structure.prior() if prior is None else np.asarray(prior, dtype=float)
        if prior.shape != (structure.n_params,):
            raise RobotModelError(f"prior has shape {prior.shape}, expected ({structure.n_params},)")
        ellipsoids = dict(ellipsoids or {})
        P = as_bodies(prior[: structure.n_body_params])
        m0 = P[:, 0]
        pos = m0[m0 > 0]
        m_ref = 0.05 * pos.mean() if pos.size else 1.0
        mass = np.where(m0 > 0, m0, m_ref)
        tr_sigma = 0.5 * (P[:, 4] + P[:, 6] + P[:, 9])  # tr Σ = ½ tr I
        with np.errstate(divide="ignore", invalid="ignore"):
            gyr = np.sqrt(np.where(m0 > 0, tr_sigma / np.where(m0 > 0, m0, 1.0), 0.0))
        length = np.empty(len(P))
        for k, b in enumerate(structure.robot.body_names):
            if np.isfinite(gyr[k]) and gyr[k] > 1e-3:
                length[k] = gyr[k]
            elif b in ellipsoids:
                length[k] = float(np.sqrt(np.mean(ellipsoids[b].semi_axes ** 2)))
            else:
                length[k] = 0.1
        per_body = np.stack([mass, mass * length, mass * length, mass * length] + [mass * length**2] * 6, axis=1)
        nj = structure.n_params - structure.n_body_params
        js = np.ones(nj) if joint_scale is None else np.asarray(joint_scale, dtype=float)
        if js.shape != (nj,) or np.any(js <= 0):
            raise ValueError(f"joint_scale must be {nj} positive numbers")
        return cls(structure, prior, np.concatenate([per_body.ravel(), js]), mass, length, ellipsoids)

    # ---- sizes and indices ---------------------------------------------------------
    @property
    def n_bodies(self) -> int:
        return self.structure.robot.n_bodies

    @property
    def body_names(self) -> tuple[str, ...]:
        return self.structure.robot.body_names

    @property
    def x0(self) -> np.ndarray:
        """The prior in scaled coordinates."""
        return self.prior / self.scale

    def body_slice(self, k: int) -> slice:
        return slice(10 * k, 10 * k + 10)

    def joint_slice(self) -> slice:
        return slice(self.structure.n_body_params, self.structure.n_params)

    def term_indices(self, term: str) -> np.ndarray:
        """Columns of ``term`` (e.g. "fv") for every actuated joint; empty if not modelled."""
        s = self.structure
        if term not in s.joint_terms:
            return np.zeros(0, dtype=int)
        return np.array([s.joint_term_index(j, term) for j in s.robot.term_joints], dtype=int)

    # ---- pseudo-inertias -------------------------------------------------------------
    def T(self, k: int) -> np.ndarray:
        """Diagonal of ``T_k``: ``J_k = T_k Ĵ_k T_k``."""
        return np.sqrt(self.body_mass[k]) * np.array([self.body_length[k]] * 3 + [1.0])

    def scaled_pseudo_inertia(self, x: cp.Expression, k: int) -> cp.Expression:
        """``Ĵ_k`` as a 4×4 affine cvxpy expression of ``x``."""
        import cvxpy as cp

        return cp.reshape(_BASIS16 @ x[self.body_slice(k)], (4, 4), order="C")

    def scaled_prior_pseudo_inertia(self, k: int) -> np.ndarray:
        return pseudo_inertia(self.x0[self.body_slice(k)])

    def bounded_bodies(self) -> Iterator[tuple[int, BoundingEllipsoid]]:
        """``(k, ellipsoid)`` for every body that has a bounding ellipsoid, in body order."""
        for k, b in enumerate(self.body_names):
            if (E := self.ellipsoids.get(b)) is not None:
                yield k, E

    def scaled_Q(self, k: int) -> np.ndarray | None:
        """``T Q T / m_k`` for body ``k`` (so ``tr(Ĵ Q̂) = tr(J Q) / m_k``), None without ellipsoid."""
        E = self.ellipsoids.get(self.body_names[k])
        if E is None:
            return None
        t = self.T(k)
        return (t[:, None] * E.Q * t[None, :]) / self.body_mass[k]

    def params(self, x: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(x)


class ConstraintBuilder(Protocol):
    """``builder(x, ctx) -> list[cp.Constraint]`` with a ``name`` and a relaxation ``hint``."""

    name: str
    hint: str

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]: ...


@dataclass
class PseudoInertiaPSD:
    """``J_k ⪰ ε T_k²`` (i.e. ``Ĵ_k ⪰ ε I``) for every body: physical consistency."""

    eps: float = 0.0
    name: str = "pseudo_inertia_psd"

    @property
    def hint(self) -> str:
        return f"lower eps (now {self.eps:g})" if self.eps > 0 else "cannot be relaxed"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        return [ctx.scaled_pseudo_inertia(x, k) >> self.eps * np.eye(4) for k in range(ctx.n_bodies)]

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        """``s = svec(Ĵ_k − ε I) ⪰ 0``: ``A = −svec-basis`` on body k's columns."""
        p, out = ctx.structure.n_params, []
        b = -self.eps * svec(np.eye(4))
        for k in range(ctx.n_bodies):
            A = np.zeros((10, p))
            A[:, ctx.body_slice(k)] = -_SVEC_BASIS
            out.append(ConicRows("psd", A, b.copy(), 4))
        return out


@dataclass
class DensityRealizable:
    """``tr(J_k Q_k) ≥ 0`` for every body that has an ellipsoid in the context."""

    name: str = "density_in_ellipsoid"
    hint: str = (f"enlarge the bounding ellipsoids (grown around the prior: {setting('contain_prior', True)}) or "
                 f"drop them ({setting('ellipsoids', False)})")

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        # tr(Ĵ Q̂) = qᵀ x_k with q = B₁₆ᵀ vec(Q̂)
        return [(_BASIS16.T @ ctx.scaled_Q(k).ravel()) @ x[ctx.body_slice(k)] >= 0 for k, _ in ctx.bounded_bodies()]

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        ks = [k for k, _ in ctx.bounded_bodies()]
        A = np.zeros((len(ks), ctx.structure.n_params))
        for r, k in enumerate(ks):
            A[r, ctx.body_slice(k)] = -(_BASIS16.T @ ctx.scaled_Q(k).ravel())
        return [ConicRows("nonneg", A, np.zeros(len(ks)))] if ks else []


@dataclass
class ComInEllipsoid:
    """CoM inside the body's ellipsoid: ``‖Σ_E^{-1/2} (h − m c_E)‖ ≤ m`` (second-order cone)."""

    name: str = "com_in_ellipsoid"
    hint: str = "enlarge the bounding ellipsoids"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        return [self._cone(x[ctx.body_slice(k)], ctx.body_length[k], E) for k, E in ctx.bounded_bodies()]

    @staticmethod
    def _cone(xk: cp.Expression, ell: float, E: BoundingEllipsoid) -> cp.Constraint:
        """One body's cone; π: m = m_s m̂, h = m_s ℓ ĥ  →  ‖Σ^{-1/2}(ℓ ĥ − m̂ c)‖ ≤ m̂."""
        import cvxpy as cp

        Wh = (E.rotation / E.semi_axes).T  # Σ^{-1/2} up to rotation
        return cp.norm(Wh @ (ell * xk[1:4] - E.center * xk[0])) <= xk[0]

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        """``s = (m̂, Wh (ℓ ĥ − m̂ c)) ∈ SOC(4)``."""
        out = []
        for k, E in ctx.bounded_bodies():
            Wh = (E.rotation / E.semi_axes).T
            blk = np.zeros((4, 4))  # rows of s in terms of (m̂, ĥ)
            blk[0, 0] = 1.0
            blk[1:, 0] = -Wh @ E.center
            blk[1:, 1:] = ctx.body_length[k] * Wh
            A = np.zeros((4, ctx.structure.n_params))
            A[:, 10 * k: 10 * k + 4] = -blk
            out.append(ConicRows("soc", A, np.zeros(4), 4))
        return out


@dataclass
class NonNegativeFriction:
    """``fv ≥ 0`` and ``fc ≥ 0`` (the terms that are modelled): the joint terms the registry marks
    ``nonnegative`` other than the rotor inertia (:class:`NonNegativeArmature`)."""

    terms: tuple[str, ...] = tuple(t for t in terms_where("nonnegative") if t not in terms_where("acceleration"))
    name: str = "friction_nonnegative"
    hint: str = "drop NonNegativeFriction (e.g. if the torque sign convention is reversed)"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        idx = np.concatenate([ctx.term_indices(t) for t in self.terms])
        return [x[idx] >= 0] if idx.size else []

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        idx = np.concatenate([ctx.term_indices(t) for t in self.terms] or [np.zeros(0, dtype=int)])
        return [ConicRows("nonneg", _select_rows(idx, ctx.structure.n_params), np.zeros(idx.size))] if idx.size else []


@dataclass
class NonNegativeArmature:
    """Rotor inertia ``armature ≥ 0`` (the ``nonnegative`` joint terms on v̇)."""

    terms: tuple[str, ...] = tuple(t for t in terms_where("nonnegative") if t in terms_where("acceleration"))
    name: str = "armature_nonnegative"
    hint: str = "drop NonNegativeArmature"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        idx = np.concatenate([ctx.term_indices(t) for t in self.terms] or [np.zeros(0, dtype=int)])
        return [x[idx] >= 0] if idx.size else []

    conic = NonNegativeFriction.conic


def _per_body(v: float | Mapping[str, float] | None, names: Sequence[str], default: float) -> np.ndarray:
    if v is None:
        return np.full(len(names), default)
    if isinstance(v, Mapping):
        unknown = [b for b in v if b not in names]
        if unknown:
            raise RobotModelError(f"mass bounds for unknown bodies {unknown}; bodies are {list(names)}")
        return np.array([float(v.get(b, default)) for b in names])
    return np.full(len(names), float(v))


@dataclass
class BodyMassBounds:
    """``lower_k ≤ m_k ≤ upper_k`` [kg]; a number applies to every body, a mapping to named ones."""

    lower: float | Mapping[str, float] | None = None
    upper: float | Mapping[str, float] | None = None
    name: str = "body_mass_bounds"
    hint: str = "widen the per-body mass bounds"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        lo = _per_body(self.lower, ctx.body_names, -np.inf)
        hi = _per_body(self.upper, ctx.body_names, np.inf)
        m_hat = x[0 : ctx.structure.n_body_params : 10]
        out = []
        if np.any(np.isfinite(lo)):
            i = np.flatnonzero(np.isfinite(lo))
            out.append(m_hat[i] >= lo[i] / ctx.body_mass[i])
        if np.any(np.isfinite(hi)):
            i = np.flatnonzero(np.isfinite(hi))
            out.append(m_hat[i] <= hi[i] / ctx.body_mass[i])
        return out

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        lo = _per_body(self.lower, ctx.body_names, -np.inf)
        hi = _per_body(self.upper, ctx.body_names, np.inf)
        p, out = ctx.structure.n_params, []
        for bound, sign in ((lo, -1.0), (hi, 1.0)):  # m̂ − lo/m ≥ 0, hi/m − m̂ ≥ 0
            i = np.flatnonzero(np.isfinite(bound))
            if i.size:
                out.append(ConicRows("nonneg", _select_rows(10 * i, p, sign), sign * bound[i] / ctx.body_mass[i]))
        return out


@dataclass
class TotalMass:
    """Total mass of all bodies: ``== value`` or within ``[lower, upper]`` [kg]."""

    value: float | None = None
    lower: float | None = None
    upper: float | None = None
    name: str = "total_mass"
    hint: str = "widen or remove the total-mass bounds"

    def __call__(self, x: cp.Variable, ctx: LmiContext) -> list[cp.Constraint]:
        ref = float(ctx.body_mass.sum())
        total = (ctx.body_mass / ref) @ x[0 : ctx.structure.n_body_params : 10]  # total mass / ref
        out = []
        if self.value is not None:
            out.append(total == self.value / ref)
        if self.lower is not None:
            out.append(total >= self.lower / ref)
        if self.upper is not None:
            out.append(total <= self.upper / ref)
        return out

    def conic(self, ctx: LmiContext) -> list[ConicRows]:
        ref = float(ctx.body_mass.sum())
        w = np.zeros((1, ctx.structure.n_params))
        w[0, 0 : ctx.structure.n_body_params : 10] = ctx.body_mass / ref
        out = []
        if self.value is not None:
            out.append(ConicRows("zero", w, np.array([self.value / ref])))
        if self.lower is not None:
            out.append(ConicRows("nonneg", -w, np.array([-self.lower / ref])))
        if self.upper is not None:
            out.append(ConicRows("nonneg", w, np.array([self.upper / ref])))
        return out


def default_constraints(eps: float = 0.0, density: bool = True) -> list[Any]:
    """``J_k ⪰ ε``, density inside the ellipsoids (if any), friction ≥ 0, armature ≥ 0."""
    out: list[Any] = [PseudoInertiaPSD(eps)]
    if density:
        out.append(DensityRealizable())
    return out + [NonNegativeFriction(), NonNegativeArmature()]


def constraint_violation(builder: ConstraintBuilder, params: np.ndarray, ctx: LmiContext) -> float:
    """Largest violation of ``builder``'s constraints at standard parameters ``params``
    (in scaled units; 0 if satisfied)."""
    import cvxpy as cp

    x = cp.Variable(ctx.structure.n_params)
    x.value = np.asarray(params, dtype=float) / ctx.scale
    viol = [np.max(np.atleast_1d(c.violation())) for c in builder(x, ctx)]
    return float(max(viol, default=0.0))

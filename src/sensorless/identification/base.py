"""Base parameters: the identifiable linear combinations of the standard parameters.

Stack the regressor W of random states and factor it with column pivoting,
W P = Q [R11 R12; 0 0], R11 (r × r). The pivoted-first r columns are independent;
the others are combinations of them, W₂ = W₁ K with K = R11⁻¹ R12. Hence

    W π = W₁ (π₁ + K π₂) = W₁ π_b,   π_b = B π,  B = [I K] Pᵀ.

``B`` (r × p) maps standard to base parameters. Structural rank uses random states
(so it does not depend on how well a given log excites the robot); how well a log
excites them is measured separately on its own data (condition number of W₁). As many slow
states (speeds log-uniform in [10⁻⁵, 1] rad/s) are appended with a weight of
:data:`SLOW_WEIGHT`: a low-speed friction column (a Stribeck term of width vs ≪ the generic
speeds) is ~zero at generic speeds and would otherwise be taken for a structurally zero column and
fixed at 0; the small weight leaves the pivoting of the other columns as it was.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import ExcitationError
from ..regressor.terms import ModelStructure

__all__ = ["BaseParameters", "base_parameters"]

#: weight of the slow random states' rows (module docstring)
SLOW_WEIGHT = 1e-3


@dataclass
class BaseParameters:
    """Base-parameter structure: ``independent`` columns and the map ``B`` (r × p)."""

    independent: np.ndarray  # indices of the r independent standard columns
    B: np.ndarray  # (r, p): π_b = B π
    labels: list[str]  # standard parameter labels (length p)
    #: RMS of each independent column of W over the random states (generic motion): the torque
    #: a unit change of each base parameter makes on a typical trajectory (None if unknown).
    column_rms: np.ndarray | None = None

    @property
    def rank(self) -> int:
        return len(self.independent)

    def base(self, params: np.ndarray) -> np.ndarray:
        return self.B @ params

    def expressions(self, digits: int = 4) -> list[str]:
        """Human-readable π_b,i = Σ_k B_ik π_k for each base parameter."""
        out = []
        for i in range(self.rank):
            terms = []
            for k in np.flatnonzero(np.abs(self.B[i]) > 1e-10):
                c = self.B[i, k]
                terms.append(self.labels[k] if abs(c - 1) < 1e-12 else f"{c:+.{digits}g}*{self.labels[k]}")
            out.append(" + ".join(terms).replace("+ -", "- ").replace("+ +", "+ "))
        return out

    def min_norm(self, pi_b: np.ndarray) -> np.ndarray:
        """Minimum-norm standard parameters with B π = π_b: π = Bᵀ (B Bᵀ)⁻¹ π_b."""
        return self.B.T @ np.linalg.solve(self.B @ self.B.T, pi_b)

    def closest_to(self, pi_b: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """Standard parameters with B π = π_b closest (Euclidean) to ``prior``."""
        return prior + self.min_norm(pi_b - self.B @ prior)

    def to_dict(self) -> dict:
        return {
            "rank": self.rank,
            "n_standard": len(self.labels),
            "independent": [self.labels[k] for k in self.independent],
            "expressions": self.expressions(),
        }


def random_states(structure: ModelStructure, n: int, rng: np.random.Generator):
    """``n`` random (Q, V, A) of ``structure``'s robot: joint positions uniform within the limits (±π
    where unlimited), a random unit-quaternion base pose for a floating base, V ~ N(0, 2²), A ~ N(0, 5²)."""
    r = structure.robot
    lo, hi = r.position_limits()
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    qj = rng.uniform(lo, hi, size=(n, len(lo)))
    base_q = None
    if r.floating_base:
        base_q = np.concatenate([rng.normal(size=(n, 3)), rng.normal(size=(n, 4))], axis=1)
        base_q[:, 3:] /= np.linalg.norm(base_q[:, 3:], axis=1, keepdims=True)
    Q = r.full_configuration(qj, base_q)
    V = rng.normal(size=(n, r.nv)) * 2.0
    A = rng.normal(size=(n, r.nv)) * 5.0
    return Q, V, A


def base_parameters(structure: ModelStructure, *, n_samples: int | None = None, tol: float = 1e-8, seed: int = 0) -> BaseParameters:
    """Structural base parameters of ``structure`` by pivoted QR on random states."""
    rng = np.random.default_rng(seed)
    p = structure.n_params
    n = n_samples or max(20, int(np.ceil(3 * p / max(structure.n_rows, 1))))
    Q, V, A = random_states(structure, n, rng)
    Z = (rng.uniform(-1.0, 1.0, (n, len(structure.robot.term_joints)))  # a friction state anywhere in [−1, 1]
         if "presliding" in getattr(structure, "joint_terms", ()) else None)
    W = structure.evaluate(Q, V, A, *(() if Z is None else (Z,))).reshape(-1, p)
    Q, V, A = random_states(structure, n, rng)
    slow = V * 10.0 ** rng.uniform(-5.0, 0.0, V.shape) / np.maximum(np.abs(V), 1e-12)  # |v| log-uniform
    W_all = np.concatenate([W, SLOW_WEIGHT * structure.evaluate(Q, slow, A, *(() if Z is None else (Z,))).reshape(-1, p)])
    rms = np.sqrt(np.mean(W ** 2, axis=0))  # per equation row over the generic states, physical units
    W = W_all
    scale = np.linalg.norm(W, axis=0)
    zero = scale <= 1e-9 * scale.max()  # structurally zero columns (round-off only)
    W[:, zero] = 0.0
    scale[zero] = 1.0
    _, R, piv = scipy.linalg.qr(W / scale, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    if d.size == 0 or d[0] == 0:
        raise ExcitationError("the regressor is identically zero: no parameter can be identified")
    r = int(np.sum(d > tol * d[0]))
    ind, dep = piv[:r], piv[r:]
    K = scipy.linalg.solve_triangular(R[:r, :r], R[:r, r:])  # in scaled coordinates
    K = K * scale[dep][None, :] / scale[ind][:, None]  # back to physical units
    K[np.abs(K) < 1e-10] = 0.0
    B = np.zeros((r, p))
    B[np.arange(r), ind] = 1.0
    B[:, dep] = K
    return BaseParameters(independent=ind, B=B, labels=list(structure.labels), column_rms=rms[ind])

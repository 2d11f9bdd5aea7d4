"""How well the data determine each identified parameter: joint motion and base-parameter spread.

Base-parameter standard deviation (the classic least-squares covariance, e.g. Swevers et
al. 1997; Gautier 1997). With per-row residual variances σ_r² and the weighted base normal
matrix A₁₁ = Σ_r A_r[ind, ind] / σ_r² = W₁ᵀ Σ⁻¹ W₁::

    cov(π_b) = (W₁ᵀ Σ⁻¹ W₁)⁻¹,   σ_πb,i = sqrt(cov_ii),   relative σ_i = σ_πb,i / |π_b,i|

computed on the equilibrated matrix S = D A₁₁ D (D = diag(A₁₁)^-½): cov = D S⁺ D, with
directions of S whose singular value is below ``rcond`` · the largest (not excited by the
data) giving σ = ∞ for every base parameter they involve. A relative σ above
:data:`MAX_RELATIVE_STD` (100 %) means the data cannot tell the value from zero.

That alone also flags parameters that are small and harmless (a product of inertia of
1e-4 ± 1e-3 kg·m² changes no torque). A base parameter is reported as *poorly identified*
when, in addition, its uncertainty matters for prediction: σ_i · rms_i exceeds the
training residual σ (median over rows), with rms_i the RMS of its regressor column over
generic motion (:attr:`BaseParameters.column_rms`, the random states of the base-parameter
analysis). The armature of a joint that barely moves (σ ≈ 0.4 kg·m² against generic
accelerations of 5 rad/s²) is; a negligible product of inertia is not.

Joint motion: a joint whose position range over the data is below :data:`NO_MOTION`
(1e-3 rad or m) never moves — its velocity- and acceleration-dependent terms (fv, fc,
armature) are unidentifiable whatever the method, so :func:`check_joint_motion` raises an
ExcitationError naming it (lock the joint or drop those terms). Below :data:`LOW_MOTION`
(0.05 rad / 0.01 m) the joint is reported as barely moving.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import ExcitationError, setting
from ..regressor.normal_equations import NormalEquations
from ..regressor.joint_terms import terms_where
from .base import BaseParameters

__all__ = [
    "MAX_RELATIVE_STD",
    "NO_MOTION",
    "LOW_MOTION",
    "JointMotion",
    "check_joint_motion",
    "base_parameter_uncertainty",
    "poorly_identified",
]

MAX_RELATIVE_STD = 1.0
NO_MOTION = {"revolute": 1e-3, "prismatic": 1e-3}
LOW_MOTION = {"revolute": 0.05, "prismatic": 0.01}
_MOTION_TERMS = terms_where("needs_motion")  # joint terms that need the joint to move (the registry's flag)


@dataclass
class JointMotion:
    """Running position range of each joint over the trajectories folded so far."""

    joint_names: tuple[str, ...]
    q_min: np.ndarray = field(default=None)  # type: ignore[assignment]
    q_max: np.ndarray = field(default=None)  # type: ignore[assignment]
    n_samples: int = 0

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        self.q_min = np.full(n, np.inf)
        self.q_max = np.full(n, -np.inf)

    def add(self, traj: Trajectory) -> Trajectory:
        idx = [traj.joint_names.index(j) for j in self.joint_names]
        if len(traj):
            self.q_min = np.minimum(self.q_min, traj.q[:, idx].min(axis=0))
            self.q_max = np.maximum(self.q_max, traj.q[:, idx].max(axis=0))
        self.n_samples += len(traj)
        return traj

    @property
    def ranges(self) -> dict[str, float]:
        return {j: float(max(hi - lo, 0.0)) for j, lo, hi in zip(self.joint_names, self.q_min, self.q_max)}


def _kind(robot, joint: str) -> str:
    return "revolute" if robot.is_revolute(joint) else "prismatic"


def check_joint_motion(motion: JointMotion, robot, joint_terms: "tuple[str, ...] | dict") -> dict[str, float]:
    """ExcitationError for a joint that never moves while it has fv/fc/stribeck/armature terms
    (``joint_terms``: the same for every joint, or ``{joint: terms}``);
    returns the joints that barely move, ``{joint: range}``."""
    ranges = motion.ranges
    joints = robot.term_joints
    per_joint = joint_terms if isinstance(joint_terms, dict) else {j: tuple(joint_terms) for j in joints}
    needs_of = {j: [t for t in per_joint.get(j, ()) if t in _MOTION_TERMS] for j in joints}
    still = {j: r for j, r in ranges.items()
             if j in joints and needs_of[j] and r < NO_MOTION[_kind(robot, j)]}
    needs = sorted({t for j in still for t in needs_of[j]}, key=list(_MOTION_TERMS).index)
    if still:
        desc = ", ".join(f"'{j}' (position range {r:.2g} {'rad' if _kind(robot, j) == 'revolute' else 'm'})"
                         for j, r in still.items())
        raise ExcitationError(
            f"the data do not excite joint(s) {desc}: they do not move over the {motion.n_samples} samples, so their "
            f"{'/'.join(needs)} terms cannot be identified; lock them ({setting('lock_joints', list(still))}), drop "
            f"those terms ({setting('joint_terms')}), or log a trajectory that moves every joint"
        )
    return {j: r for j, r in ranges.items() if r < LOW_MOTION[_kind(robot, j)]}


def _equilibrated(A11: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.sqrt(np.clip(np.diag(A11), 0.0, None))
    live = d > 1e-12 * max(d.max(), 1e-300)
    dd = np.where(live, d, 1.0)
    S = A11 / np.outer(dd, dd)
    S[~live, :] = 0.0
    S[:, ~live] = 0.0
    return S, dd, live


def base_parameter_uncertainty(
    ne: NormalEquations, base: BaseParameters, sigma: np.ndarray, rcond: float = 1e-6
) -> np.ndarray:
    """Standard deviation of each base parameter (∞ where the data leave it unexcited).

    Which directions are excited is decided on the unweighted equations (as
    :func:`~.least_squares.excitation_check` does); the row weights 1/σ_r² are floored at
    σ_r ≥ 1e-3 · max σ so a near noise-free row cannot make the weighted matrix singular.
    """
    sigma = np.asarray(sigma, dtype=float)
    ind = base.independent
    if ind.size == 0:
        return np.zeros(0)
    s = np.maximum(sigma, 1e-3 * max(float(np.max(sigma)) if sigma.size else 0.0, 1e-300))
    with np.errstate(all="ignore"):
        A, _, _ = ne.total()
        Aw, _, _ = ne.total(1.0 / s**2)
        A11, Aw11 = A[np.ix_(ind, ind)], Aw[np.ix_(ind, ind)]
        if not (np.all(np.isfinite(A11)) and np.all(np.isfinite(Aw11))):
            return np.full(base.rank, np.inf)
        try:
            S, _, live = _equilibrated(A11)
            lam, U = np.linalg.eigh(S)
            sv = np.sqrt(np.maximum(lam, 0.0))
            weak = sv <= rcond * max(sv.max(), 1e-300)
            unexcited = (np.abs(U[:, weak]) > 1e-3).any(axis=1) | ~live
            Sw, dw, _ = _equilibrated(Aw11)
            lw, Uw = np.linalg.eigh(Sw)
        except np.linalg.LinAlgError:
            return np.full(base.rank, np.inf)
        keep = lw > (rcond * max(np.sqrt(max(lw.max(), 0.0)), 1e-300)) ** 2
        var_z = (Uw[:, keep] ** 2) @ (1.0 / lw[keep]) if keep.any() else np.zeros(len(dw))
        std = np.sqrt(var_z) / dw
    std[unexcited] = np.inf
    return std


def poorly_identified(
    base: BaseParameters, values: np.ndarray, std: np.ndarray, noise: float, limit: float = MAX_RELATIVE_STD
) -> tuple[np.ndarray, list[dict]]:
    """Relative standard deviations σ_i / |π_b,i|, and the base parameters above ``limit`` whose
    torque uncertainty σ_i · rms_i exceeds ``noise`` (module docstring), worst first, as
    ``{"base_parameter", "value", "std", "relative_std", "torque_std"}``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(np.abs(values) > 0, std / np.abs(values), np.inf)
        rel = np.where(np.isnan(rel), np.inf, rel)
        rms = base.column_rms if base.column_rms is not None else np.full(len(std), np.inf)
        impact = np.where(std > 0, std * rms, 0.0)
    expr = base.expressions()
    bad = [i for i in np.argsort(-rel, kind="stable") if rel[i] > limit and not impact[i] <= noise]
    return rel, [{"base_parameter": expr[i], "value": float(values[i]),
                  "std": float(std[i]) if np.isfinite(std[i]) else None,
                  "relative_std": float(rel[i]) if np.isfinite(rel[i]) else None,
                  "torque_std": float(impact[i]) if np.isfinite(impact[i]) else None} for i in bad]

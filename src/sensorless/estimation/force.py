"""Cartesian force from external joint torque: F = (Jᵀ)⁺ τ_ext, damped near singularities.

External torque: what the dynamic model (and an optional learned residual) does not explain,

    τ_ext = τ_measured − τ_model(q, q̇, q̈) − τ_residual,

on every row whose generalized force is known: the actuated joints (measured), and the
unactuated coordinates, whose generalized force is 0 — passive joints (a leg's rail) and a
floating base's 6 rows. There τ_ext = −τ_model: on a hopping leg on a vertical rail, the rail
row alone gives the vertical foot force from the identified mass and accelerations. The model's
equations are the unmapped ones (no contact projection: the contact force is what is estimated).

A wrench F applied at a frame produces τ_ext = Jᵀ F, with J the frame Jacobian (rows:
linear then angular, in the chosen reference: ``local``, ``world`` or
``local_world_aligned``, Pinocchio's conventions; the estimated wrench is expressed in the
same reference). Per sample we solve the damped least-squares problem

    F = argmin ‖Jᵀ F − τ_ext‖² + λ² ‖F‖²  =  U diag(σ / (σ² + λ²)) Vᵀ τ_ext,   J = U Σ Vᵀ,

with an adaptive damping (Nakamura & Hanafusa; Chiaverini) that is zero away from
singularities and grows as the smallest singular value σ_min drops below ε:

    λ² = λ_max² (1 − (σ_min / ε)²)  if σ_min < ε,  else 0.

The gain of any direction is then at most 1/(2λ): the estimate stays bounded at a
singularity instead of blowing up. A direction with σ = 0 (numerically: below ``UNOBSERVABLE`` · max(m, n) · ε_machine
times the largest σ of J, the rank rule of ``numpy.linalg.matrix_rank``; or missing because J has
fewer columns than rows) is *unobservable*: no joint
torque measures a force along it (a frame that does not move that way under the joints). The
force components with a share of such a direction (Σ U²_{c,null} > 10⁻⁶) are NaN on that sample,
never 0, and ``unobservable`` flags them. All samples are solved at once (batched SVD); only the
Jacobians are computed per sample, by Pinocchio.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Sequence

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError, ShapeMismatchError
from ..robot import Robot

__all__ = [
    "COMPONENTS",
    "REFERENCES",
    "CartesianForceEstimator",
    "ForceEstimate",
    "damped_least_squares",
    "damped_least_squares_one",
    "external_torque",
    "frame_jacobians",
]

Reference = Literal["local", "world", "local_world_aligned"]
REFERENCES: dict[str, pin.ReferenceFrame] = {
    "local": pin.LOCAL,
    "world": pin.WORLD,
    "local_world_aligned": pin.LOCAL_WORLD_ALIGNED,
}
_COMPONENTS = {"linear": slice(0, 3), "angular": slice(3, 6), "wrench": slice(0, 6)}
#: named component sets; any comma-separated subset of the labels works too ("fx,fz" for a planar leg)
COMPONENTS = tuple(_COMPONENTS)
_LABELS = ("fx", "fy", "fz", "mx", "my", "mz")


def _component_index(components: str) -> np.ndarray:
    """Rows of the 6-D wrench for ``components``: a named set or labels such as "fz" or "fx,fz"."""
    if components in _COMPONENTS:
        return np.arange(6)[_COMPONENTS[components]]
    labels = [c.strip() for c in str(components).split(",") if c.strip()]
    bad = [c for c in labels if c not in _LABELS]
    if not labels or bad or len(set(labels)) != len(labels):
        raise RobotModelError(f"unknown components '{components}'; choose {', '.join(COMPONENTS)} or "
                              f"comma-separated labels from {', '.join(_LABELS)} (e.g. fx,fz)")
    return np.array(sorted(_LABELS.index(c) for c in labels), dtype=int)


def _reference(name: str) -> pin.ReferenceFrame:
    try:
        return REFERENCES[name.lower()]
    except KeyError:
        raise RobotModelError(f"unknown reference '{name}'; choose from {sorted(REFERENCES)}") from None


def frame_jacobians(robot: Robot, Q: np.ndarray, frame: str, reference: str = "local_world_aligned") -> np.ndarray:
    """Frame Jacobians (N, 6, nv) at configurations Q (N, nq), one Pinocchio call per sample.

    For a robot driven through a transmission (a coordinate robot: tree joints q = Gθ + q₀,
    e.g. the dVRK PSM in motor coordinates) Q holds the coordinates θ and the Jacobian is
    mapped to them, J_θ = J_tree(Gθ + q₀) · ∂q/∂θ = J_tree G (so τ_θ = J_θᵀ F = Gᵀ J_treeᵀ F).
    """
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    if Q.shape[1] != robot.nq:
        raise ShapeMismatchError(f"configurations have {Q.shape[1]} columns, robot '{robot.name}' has nq={robot.nq}")
    fid = robot.frame_id(frame)
    ref = _reference(reference)
    model, data = robot.model, robot.data
    G = robot.transmission_matrix
    Qp = robot.tree_state(Q)[0] if G is not None else Q
    out = np.empty((Q.shape[0], 6, model.nv))
    for i in range(Q.shape[0]):
        out[i] = pin.computeFrameJacobian(model, data, Qp[i], fid, ref)
    return out if G is None else out @ G


@dataclass
class DampedSolution:
    F: np.ndarray  # (N, m)
    sigma_min: np.ndarray  # (N,)
    damping: np.ndarray  # (N,) λ
    unobservable: np.ndarray | None = None  # (N, m) bool: no joint torque measures this component


UNOBSERVABLE = 10.0  # margin over matrix_rank's tolerance


def damped_least_squares(
    J: np.ndarray, tau: np.ndarray, *, sigma_threshold: float = 0.01, lambda_max: float = 0.02
) -> DampedSolution:
    """Batched F = argmin ‖J_iᵀ F − τ_i‖² + λ_i²‖F‖² for J (N, m, n), τ (N, n).

    λ_i is the adaptive damping of the module docstring (``sigma_threshold`` = ε); with
    ``lambda_max = 0`` this is the plain pseudo-inverse solution.
    """
    J = np.asarray(J, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if J.ndim != 3 or tau.shape != (J.shape[0], J.shape[2]):
        raise ShapeMismatchError(f"need J (N, m, n) and tau (N, n); got J {J.shape}, tau {tau.shape}")
    U, s, Vt = np.linalg.svd(J, full_matrices=False)  # (N,m,k) (N,k) (N,k,n)
    k = s.shape[1]
    unobservable, tol = _unobservable(J, s)
    # smallest singular value of the observable directions (the unobservable ones are NaN, not damped)
    smin = np.where(s > tol[:, None], s, np.inf).min(axis=1, initial=np.inf)
    smin[~np.isfinite(smin)] = 0.0
    ratio = np.clip(smin / sigma_threshold, 0.0, 1.0) if sigma_threshold > 0 else np.ones_like(smin)
    lam2 = lambda_max**2 * (1.0 - ratio**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = s**2 + lam2[:, None]
        gain = np.where(denom > 0, s / denom, 0.0)
    F = np.einsum("nmk,nk,nk->nm", U, gain, np.einsum("nkj,nj->nk", Vt, tau))
    F[unobservable] = np.nan
    return DampedSolution(F, smin, np.sqrt(lam2), unobservable)


def damped_least_squares_one(J: np.ndarray, tau: np.ndarray, *, sigma_threshold: float = 0.01,
                             lambda_max: float = 0.02) -> np.ndarray:
    """F (m,) of :func:`damped_least_squares` for one sample, J (m, n), τ (n,): the same rule and
    numbers without the batch overhead (a streaming loop: ``sensorless stream``)."""
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    sv = s.tolist()  # descending
    tol = UNOBSERVABLE * max(J.shape) * _EPS * max(sv[0] if sv else 0.0, 1e-300)
    seen = [x for x in sv if x > tol]
    smin = seen[-1] if seen else 0.0
    ratio = min(max(smin / sigma_threshold, 0.0), 1.0) if sigma_threshold > 0 else 1.0
    lam2 = lambda_max**2 * (1.0 - ratio**2)
    gain = [x / (x * x + lam2) if x * x + lam2 > 0 else 0.0 for x in sv]
    F = U @ (np.array(gain) * (Vt @ tau))
    if len(seen) < J.shape[0]:
        F[_unobservable(J[None], s[None])[0][0]] = np.nan
    return F


_EPS = float(np.finfo(float).eps)


def _unobservable(J: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, m) components of F with a share > 1e-6 of a direction Jᵀ does not see (σ ≈ 0 or missing),
    and the per-sample σ tolerance."""
    N, m, _ = J.shape
    out = np.zeros((N, m), dtype=bool)
    tol = UNOBSERVABLE * max(J.shape[1:]) * np.finfo(float).eps * np.maximum(s.max(axis=1, initial=0.0), 1e-300)
    rank = np.sum(s > tol[:, None], axis=1)
    for i in np.flatnonzero(rank < m):
        Uf = np.linalg.svd(J[i])[0]  # full U: the last m − rank columns span what Jᵀ maps to zero
        out[i] = np.sum(Uf[:, rank[i]:] ** 2, axis=1) > 1e-6
    return out, tol


def external_torque(
    measured: np.ndarray, model: np.ndarray, residual: np.ndarray | None = None
) -> np.ndarray:
    """τ_ext = τ_measured − τ_model (− τ_residual), arrays (N, n)."""
    measured, model = np.asarray(measured, float), np.asarray(model, float)
    if measured.shape != model.shape:
        raise ShapeMismatchError(f"measured torque {measured.shape} and model torque {model.shape} differ")
    out = measured - model
    if residual is not None:
        residual = np.asarray(residual, float)
        if residual.shape != out.shape:
            raise ShapeMismatchError(f"residual torque {residual.shape} does not match {out.shape}")
        out = out - residual
    return out


@dataclass
class ForceEstimate:
    """Estimated force/wrench per sample with the diagnostics of the damped solve."""

    t: np.ndarray
    F: np.ndarray  # (N, m)
    labels: list[str]
    frame: str
    reference: str
    tau_ext: np.ndarray
    sigma_min: np.ndarray
    damping: np.ndarray
    settings: dict = field(default_factory=dict)
    unobservable: np.ndarray | None = None  # (N, m) bool; F is NaN there (see the module docstring)

    @property
    def n_unobservable(self) -> int:
        """Samples with at least one component no joint torque measures."""
        return 0 if self.unobservable is None else int(np.any(self.unobservable, axis=1).sum())

    def arrays(self) -> dict[str, np.ndarray]:
        """Arrays for ``np.savez`` (plain dtypes only, loadable without pickle)."""
        unobs = np.zeros(self.F.shape, dtype=bool) if self.unobservable is None else self.unobservable
        return {
            "t": self.t, "force": self.F, "labels": np.array(self.labels), "tau_ext": self.tau_ext,
            "sigma_min": self.sigma_min, "damping": self.damping, "unobservable": unobs,
            "frame": np.array(self.frame), "reference": np.array(self.reference),
        }


class CartesianForceEstimator:
    """F = (Jᵀ)⁺ τ_ext at ``frame``, expressed in ``reference``.

    ``components``: "linear" (3 forces: a pure force at the frame origin — the usual choice
    for a tool tip), "angular" (3 moments), "wrench" (6), or labels such as "fz" or "fx,fz".
    The equations are the rows of known generalized force (module docstring): a floating base's 6,
    then the term joints (actuated, then passive). ``joints``: which of these joints to use (default
    all; e.g. drop wrist joints whose torques are noisy); a floating base's rows are always used.
    ``sigma_threshold`` ε and ``lambda_max`` set the damping (units of the Jacobian rows).
    """

    def __init__(
        self,
        robot: Robot,
        frame: str,
        reference: str = "local_world_aligned",
        *,
        components: str = "linear",
        joints: Sequence[str] | None = None,
        sigma_threshold: float = 0.01,
        lambda_max: float = 0.02,
    ) -> None:
        robot.frame_id(frame)
        _reference(reference)
        self._comp = _component_index(components)
        self.robot, self.frame, self.reference, self.components = robot, frame, reference.lower(), components
        term = tuple(robot.term_joints)
        self.joints = tuple(joints) if joints is not None else term
        bad = [j for j in self.joints if j not in term]
        if bad:
            raise RobotModelError(f"joints {bad} are neither actuated nor passive joints of '{robot.name}' ({list(term)})")
        nb = 6 if robot.floating_base else 0
        #: velocity indices of the rows of known generalized force (module docstring) and their names
        self.known = np.concatenate([np.arange(nb), robot.term_v_indices]).astype(int)
        self.known_names = [f"base_{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")][:nb] + list(term)
        self._sel = np.array(list(range(nb)) + [nb + term.index(j) for j in self.joints], dtype=int)
        self._act = nb + np.arange(robot.n_actuated)  # the actuated rows among the known ones
        self._v = self.known[self._sel]
        self.sigma_threshold, self.lambda_max = float(sigma_threshold), float(lambda_max)

    @property
    def labels(self) -> list[str]:
        return [_LABELS[i] for i in self._comp]

    @property
    def row_names(self) -> list[str]:
        """The equations used (a floating base's rows, then the chosen joints)."""
        return [self.known_names[k] for k in self._sel]

    def jacobians(self, Q: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Rows of the chosen components, columns of the chosen equations (velocity indices ``rows``,
        default the chosen known rows): (N, m, n_rows)."""
        J = frame_jacobians(self.robot, Q, self.frame, self.reference)
        return J[:, self._comp][:, :, self._v if rows is None else rows]

    def from_external_torque(self, Q: np.ndarray, tau_ext: np.ndarray, t: np.ndarray | None = None) -> ForceEstimate:
        """Force from Pinocchio configurations Q (N, nq) and τ_ext (N, n_known) on the rows of known
        generalized force (:attr:`known_names`), or (N, n_actuated) on the actuated joints only."""
        tau_ext = np.atleast_2d(np.asarray(tau_ext, dtype=float))
        Q = np.atleast_2d(Q)
        n_known, n_act = len(self.known), self.robot.n_actuated
        if tau_ext.shape == (Q.shape[0], n_known):
            sel = self._sel
        elif tau_ext.shape == (Q.shape[0], n_act):  # actuated rows only (e.g. a black-box torque model)
            sel = np.array([k for k in self._sel if k in set(self._act.tolist())], dtype=int)
            full = np.zeros((Q.shape[0], n_known))
            full[:, self._act] = tau_ext
            tau_ext = full
        else:
            raise ShapeMismatchError(
                f"tau_ext has shape {tau_ext.shape}; expected ({Q.shape[0]}, {n_known}) (rows {self.known_names}) "
                f"or ({Q.shape[0]}, {n_act}) (actuated joints {list(self.robot.actuated_joints)})"
            )
        tau_ext = tau_ext[:, sel]
        if not np.all(np.isfinite(tau_ext)):
            bad = int(np.argwhere(~np.isfinite(tau_ext))[0, 0])
            raise DataError(f"tau_ext is not finite at sample {bad}")
        sol = damped_least_squares(self.jacobians(Q, self.known[sel]), tau_ext,
                                   sigma_threshold=self.sigma_threshold, lambda_max=self.lambda_max)
        return ForceEstimate(
            t=np.arange(Q.shape[0], dtype=float) if t is None else np.asarray(t, float),
            F=sol.F, labels=self.labels, frame=self.frame, reference=self.reference, tau_ext=tau_ext,
            sigma_min=sol.sigma_min, damping=sol.damping, settings=self.settings(), unobservable=sol.unobservable,
        )

    def estimate(self, traj: Trajectory, model, residual=None) -> ForceEstimate:
        """τ_ext = τ_measured − model.predict(traj) (− residual.predict_residual(traj)) → F.

        ``model`` is a fitted torque model: a physical one (``structure_`` and ``parameters_``, e.g.
        :class:`~sensorless.torque_models.PhysicalModel`, identified with or without contacts) is evaluated
        on the rows of known generalized force without its row map (module docstring); any other
        model's ``predict`` gives the actuated rows (a hybrid or a learned model). ``residual``: an
        optional object with ``predict_residual(traj)`` (a learned correction, actuated rows).
        """
        from ..regressor.terms import ModelStructure

        structure = getattr(model, "structure_", None) or ModelStructure(self.robot, joint_terms=())
        params = getattr(model, "parameters_", None)
        res = None if residual is None else residual.predict_residual(traj)
        if params is not None and structure.robot.transmission_matrix is None:
            eom = structure.equations_of_motion()  # unmapped, on the known rows; parameters: the first n_params
            pred = eom.torques(np.asarray(params)[: eom.n_params], traj)
            if res is not None:
                pred[:, eom.actuated_rows] += res
            tau_ext = external_torque(eom.target(traj), pred)
            structure = eom
        else:
            tau_ext = external_torque(structure.target(traj), model.predict(traj), res)
        Q = structure.state(traj)[0] if traj.v is not None and traj.a is not None else self.robot.full_configuration(
            traj.select_joints(list(self.robot.joint_names)).q)
        return self.from_external_torque(Q, tau_ext, traj.t)

    def settings(self) -> dict:
        return {
            "frame": self.frame, "reference": self.reference, "components": self.components,
            "joints": list(self.joints), "sigma_threshold": self.sigma_threshold, "lambda_max": self.lambda_max,
        }

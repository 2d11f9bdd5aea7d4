"""A payload's regressor and its estimate: φ = [m, m c, I_f] of a body fixed to a frame
(:mod:`.payload` for the identification), τ_p = Jᵀ Φ_f(φ) on the actuated rows."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..robot import Robot

__all__ = ["JointConsistency", "PayloadEstimate", "payload_regressor", "point_mass_parameters"]


def payload_regressor(robot: Robot, Q: np.ndarray, V: np.ndarray, A: np.ndarray, frame: str) -> np.ndarray:
    """Y_p (N, n_actuated, 10): actuated joint torques per unit payload parameter at ``frame``.

    For a coordinate robot (transmission q = Gθ + q₀) Q, V, A are coordinate arrays θ, θ̇, θ̈
    and the rows are the coordinates' generalised forces, Gᵀ J_fᵀ Φ_f."""
    fid = robot.frame_id(frame)
    model, data = robot.model, robot.data
    act = robot.actuated_v_indices
    G = robot.transmission_matrix
    if G is not None:
        Q, V, A = robot.tree_state(Q, V, A)
    out = np.empty((Q.shape[0], len(act), 10))
    for i in range(Q.shape[0]):
        pin.rnea(model, data, Q[i], V[i], A[i])
        Phi = pin.frameBodyRegressor(model, data, fid).copy()
        J = pin.computeFrameJacobian(model, data, Q[i], fid, pin.LOCAL)
        Y = J.T @ Phi
        out[i] = (Y if G is None else G.T @ Y)[act]
    return out


def _skew_sq(c: np.ndarray) -> np.ndarray:
    return (c @ c) * np.eye(3) - np.outer(c, c)


def point_mass_parameters(mass: float, com: np.ndarray) -> np.ndarray:
    """φ of a point mass at ``com`` (frame coordinates): [m, m c, m S(c)], S(c) = |c|² 1 − c cᵀ."""
    com = np.asarray(com, dtype=float)
    I = mass * _skew_sq(com)
    return np.concatenate([[mass], mass * com, [I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]]])


@dataclass
class JointConsistency:
    """The mass one joint alone implies vs the mass the other joints imply (payload shape fixed)."""

    joint: str
    mass: float  # m_j from this joint's equation alone
    std: float  # its HAC standard error σ_j
    others_mass: float  # m from every other informative joint
    others_std: float
    z: float  # (m_j − m_others) / √(σ_j² + σ_others²)
    share: float  # fraction of the payload information this joint carries
    informative: bool  # σ_j < |m|
    flagged: bool
    offset: float | None  # offset of this joint in its own fit, when fitted

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("joint", "mass", "std", "others_mass", "others_std", "z", "share",
                                              "informative", "flagged", "offset")}


@dataclass
class PayloadEstimate:
    """Identified payload at ``frame``; ``parameters`` in Pinocchio order (frame axes)."""

    frame: str
    mode: str
    parameters: np.ndarray
    mass_std: float
    mass_std_analytic: float
    mass_std_bootstrap: float | None
    com_std: np.ndarray | None
    consistent: bool
    min_pseudo_inertia_eig: float
    residual_rms_before: np.ndarray
    residual_rms_after: np.ndarray
    joints: list[str]
    n_samples: int
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    mass_std_hac: float | None = None
    covariance: np.ndarray | None = None  # HAC covariance of φ (10 × 10)
    offsets: np.ndarray | None = None  # per-joint offsets (when fitted)
    per_joint: list[JointConsistency] = field(default_factory=list)
    gravity: float = 9.81
    determinacy: dict = field(default_factory=dict)  # per quantity: "data", "undetermined", ... (.payload_determinacy)
    headline_excludes: list[str] = field(default_factory=list)  # flagged joints left out of the estimate

    @property
    def mass(self) -> float:
        return float(self.parameters[0])

    @property
    def weight(self) -> float:
        """m·g [N] (|g| of the robot model)."""
        return self.mass * self.gravity

    @property
    def com(self) -> np.ndarray:
        m = self.mass
        return self.parameters[1:4] / m if m > 0 else np.full(3, np.nan)

    @property
    def inertia_com(self) -> np.ndarray:
        """Rotational inertia about the CoM (frame axes)."""
        p = self.parameters
        I = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
        return I - self.mass * _skew_sq(self.com) if self.mass > 0 else I

    @property
    def mass_at_bound(self) -> bool:
        """The mass sits at its bound m = 0: not an estimate."""
        return self.determinacy.get("mass") == "at bound: not determined"

    @property
    def flagged_joints(self) -> list[str]:
        return [c.joint for c in self.per_joint if c.flagged]

    def __str__(self) -> str:
        c = ", ".join(f"{x * 1e3:.1f}" for x in self.com)
        if self.mass_at_bound:
            return f"payload at '{self.frame}': m at its bound 0 (not determined) [{self.mode}]"
        out = f"payload at '{self.frame}': m = {self.mass:.4f} ± {self.mass_std:.4f} kg, CoM = ({c}) mm [{self.mode}]"
        if self.flagged_joints:
            out += f"; joint(s) {self.flagged_joints} contradict the others and are left out"
        return out

    def to_dict(self) -> dict:
        return {
            "frame": self.frame, "mode": self.mode, "mass": self.mass, "mass_std": self.mass_std,
            "weight_N": self.weight, "weight_std_N": self.mass_std * self.gravity,
            "mass_std_analytic": self.mass_std_analytic, "mass_std_hac": self.mass_std_hac,
            "mass_std_bootstrap": self.mass_std_bootstrap,
            "com": self.com.tolist(), "com_std": None if self.com_std is None else self.com_std.tolist(),
            "inertia_com": self.inertia_com.tolist(), "parameters": self.parameters.tolist(),
            "covariance": None if self.covariance is None else self.covariance.tolist(),
            "offsets": None if self.offsets is None else dict(zip(self.joints, self.offsets.tolist())),
            "per_joint": [c.to_dict() for c in self.per_joint], "flagged_joints": self.flagged_joints,
            "headline_excludes": list(self.headline_excludes), "determinacy": dict(self.determinacy),
            "consistent": self.consistent, "min_pseudo_inertia_eig": self.min_pseudo_inertia_eig,
            "residual_rms_before": dict(zip(self.joints, self.residual_rms_before.tolist())),
            "residual_rms_after": dict(zip(self.joints, self.residual_rms_after.tolist())),
            "n_samples": self.n_samples, "settings": self.settings, "diagnostics": self.diagnostics,
        }

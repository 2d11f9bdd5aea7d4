"""Gains of the torque controller and their closed-loop (Δq) form.

The controller (Del Prete et al., IJHR 2016) sends the position-controlled drive

    Δq = q_cmd − q = Kτ τ* + Kv q̇                                   (feedforward motor model)
    τ* = τ_d + Kp (τ_d − τ̂) + Ki ∫(τ_d − τ̂)                         (torque feedback)
    τ_d = M q̈_d + h − Jᵀ f* + Ks e_q + Kd ė_q,   f* = f_d + Kf e_f    (inverse dynamics)

with e_q = q_d − q, e_f = f_d − f̂. Write τ_ff = M q̈_d + h − Jᵀ f_d (pure model
feedforward) and substitute (Ki = 0):

    Δq = (Kτ + K8) τ_ff − K8 τ̂ + K6 e_q + K7 ė_q − (K9 ∘ Jᵀ) e_f + Kv q̇

    K8 = Kτ Kp                [rad/Nm]   torque-feedback gain
    K6 = Kτ (1 + Kp) Ks       [rad/rad]  position gain
    K7 = Kτ (1 + Kp) Kd       [s]        velocity gain
    K9 = Kτ (1 + Kp) ⊗ Kf     [rad/N]    force gain, K9[j, k] = Kτ_j (1 + Kp_j) Kf_k

(per joint j; Kf per wrench component k; ∘ is the element-wise product). This is our
reconstruction of the paper's (K6 … K9) parametrisation, chosen so that plain position
control — q_cmd = q_d, i.e. Δq = e_q — is exactly K6 = 1, K7 = K8 = K9 = 0 with no
feedforward. "Torque control at K6 = 1" therefore has the *same* stiffness on the position
error as position control, plus the model feedforward and the torque feedback; K6 < 1
is a more compliant controller. Inverse: Kp = K8 / Kτ, Ks = K6 / (Kτ + K8),
Kd = K7 / (Kτ + K8), Kf = K9[j, :] / (Kτ_j + K8_j) (the same for every joint).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError

__all__ = ["DeltaQGains", "TorqueGains", "damped_gains", "from_delta_q_gains", "to_delta_q_gains"]


def _vec(x, n: int, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    try:
        x = np.broadcast_to(x, (n,)).copy()
    except ValueError:
        raise DataError(f"gain '{name}' must be a scalar or have {n} entries, got shape {x.shape}") from None
    if not np.all(np.isfinite(x)):
        raise DataError(f"gain '{name}' is not finite: {x}")
    return x


@dataclass
class TorqueGains:
    """Gains of the torque controller (per joint; ``kf`` per wrench component [f; m])."""

    kp: np.ndarray
    ks: np.ndarray
    kd: np.ndarray
    kf: np.ndarray = field(default_factory=lambda: np.zeros(6))
    ki: np.ndarray | float = 0.0

    def __post_init__(self) -> None:
        n = np.size(self.kp) if np.ndim(self.kp) else max(np.size(self.ks), np.size(self.kd), 1)
        self.kp, self.ks, self.kd = (_vec(v, n, k) for v, k in ((self.kp, "kp"), (self.ks, "ks"), (self.kd, "kd")))
        self.ki = _vec(self.ki, n, "ki")
        self.kf = _vec(self.kf, 6, "kf")

    def to_dict(self) -> dict:
        return {k: np.asarray(v).tolist() for k, v in self.__dict__.items()}


@dataclass
class DeltaQGains:
    """Closed-loop (Δq) gains: K6, K7, K8 per joint, K9 (n_joints, 6)."""

    k6: np.ndarray
    k7: np.ndarray
    k8: np.ndarray
    k9: np.ndarray

    def to_dict(self) -> dict:
        return {k: np.asarray(v).tolist() for k, v in self.__dict__.items()}


def to_delta_q_gains(g: TorqueGains, k_tau) -> DeltaQGains:
    """(Kp, Ks, Kd, Kf) → (K6, K7, K8, K9) for the motor model's Kτ (see module docstring)."""
    kt = _vec(k_tau, g.kp.size, "k_tau")
    if np.any(kt <= 0):
        raise DataError(f"Kτ must be positive, got {kt}")
    a = kt * (1.0 + g.kp)
    return DeltaQGains(k6=a * g.ks, k7=a * g.kd, k8=kt * g.kp, k9=np.outer(a, g.kf))


def from_delta_q_gains(d: DeltaQGains, k_tau, rtol: float = 1e-9) -> TorqueGains:
    """(K6, K7, K8, K9) → (Kp, Ks, Kd, Kf). DataError if K9 is not of the form a ⊗ Kf."""
    k6 = np.atleast_1d(np.asarray(d.k6, float))
    n = k6.size
    kt = _vec(k_tau, n, "k_tau")
    k7, k8 = _vec(d.k7, n, "k7"), _vec(d.k8, n, "k8")
    k9 = np.broadcast_to(np.asarray(d.k9, float), (n, 6))
    a = kt + k8
    if np.any(a <= 0) or np.any(kt <= 0):
        raise DataError(f"Kτ + K8 must be positive, got Kτ={kt}, K8={k8}")
    kf_rows = k9 / a[:, None]
    kf = kf_rows[0]
    if not np.allclose(kf_rows, kf, rtol=rtol, atol=1e-12 * max(1.0, np.abs(kf).max())):
        raise DataError("K9 rows are not proportional to Kτ + K8: no joint-independent force gain Kf reproduces them")
    return TorqueGains(kp=k8 / kt, ks=k6 / a, kd=k7 / a, kf=kf)


def damped_gains(k6, k_tau, kp, inertia, zeta: float = 0.3, kf=0.0) -> TorqueGains:
    """Gains with position gain ``k6`` (Δq form) and damping ratio ``zeta`` on each joint,
    taking ``inertia`` [kg m²] as the joint's apparent inertia: Ks = K6 / (Kτ (1 + Kp)),
    Kd = 2 ζ √(Ks I). Keep ζ modest (default 0.3): the velocity comes from a causal
    filter of the encoders, whose lag makes a high derivative gain chatter."""
    kt = np.asarray(k_tau, float)
    kp = np.broadcast_to(np.asarray(kp, float), kt.shape)
    ks = np.broadcast_to(np.asarray(k6, float), kt.shape) / (kt * (1.0 + kp))
    kd = 2.0 * zeta * np.sqrt(ks * np.asarray(inertia, float))
    return TorqueGains(kp=kp, ks=ks, kd=kd, kf=kf)

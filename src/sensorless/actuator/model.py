"""Actuator models of a position-controlled joint (high-ratio gearbox, PD on the motor).

A stiff position loop turns the angle error into motor current, hence into torque. At
steady state the command offset Δq = q_cmd − q therefore tells the joint torque τ
(Del Prete et al., IJHR 2016, HRP-2):

    Δq = Kτ τ + Kv q̇ + Kc sgn(q̇)                                     (MotorModel)

Kτ [rad/Nm] is the inverse stiffness of the position loop, Kv [s] collects the loop's
velocity damping and the viscous friction, Kc [rad] the Coulomb friction. With the motor
current i measured instead, the same physics reads

    τ = K1 i − Fv q̇ − Fc sgn(q̇)                                       (CurrentModel)

A :class:`PiecewiseLinearModel` replaces the linear τ term by a continuous three-segment
function of τ per sign of q̇ (dead zone / stiction band around τ = 0).

"Over-estimation" of a sample: the model predicts a larger |Δq| than measured, in the
direction of the measured Δq: z = sgn(Δq) (Δq_model − Δq) > 0 (sgn 0 := +1).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import ShapeMismatchError

__all__ = [
    "CurrentModel",
    "MotorModel",
    "PiecewiseLinearModel",
    "over_estimation",
    "over_estimation_fraction",
]


def _sgn(x: np.ndarray) -> np.ndarray:
    return np.sign(x)


def joint_names_or_default(names, n: int, what: str | None = None) -> tuple[str, ...]:
    """``names`` as a tuple (default ``joint0 … joint{n-1}``); with ``what``, there must be ``n``."""
    names = tuple(names) or tuple(f"joint{j}" for j in range(n))
    if what is not None and len(names) != n:
        raise ShapeMismatchError(f"{len(names)} joint names for {n} {what}")
    return names


def _per_joint(x, n: int) -> np.ndarray:
    """``x`` (one value, or one per joint) as a float array of shape (n,)."""
    return np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()


def _log_columns(n: int, tau, dq, delta_q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``tau``, ``dq``, ``delta_q`` as (N, n) arrays for a model of ``n`` joints (:func:`_cols`)."""
    return tuple(_cols(a, n, w) for a, w in ((tau, "tau"), (dq, "dq"), (delta_q, "delta_q")))


def _cols(x, n: int, what: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim == 1 and n == 1:
        x = x[:, None]
    x = np.atleast_2d(x)
    if x.shape[-1] != n:
        raise ShapeMismatchError(f"{what} has {x.shape[-1]} columns, the actuator model has {n} joints")
    return x


def over_estimation(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Boolean mask, True where the prediction exceeds |measured| in measured's direction."""
    s = np.where(measured >= 0, 1.0, -1.0)
    return s * (predicted - measured) > 0


def over_estimation_fraction(predicted: np.ndarray, measured: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Per-column fraction of over-estimated samples (see :func:`over_estimation`), over the
    ``valid`` samples only when a mask is given."""
    over = over_estimation(np.asarray(predicted, float), np.asarray(measured, float))
    if valid is None:
        return over.mean(axis=0)
    return (over & valid).sum(axis=0) / np.maximum(valid.sum(axis=0), 1)


@dataclass
class _JointwiseModel:
    """What the actuator models share: per-joint parameter arrays (named in ``ARRAYS``, first
    axis the joint), the joints' names, the fit that made them and its diagnostics; a dict form
    that round-trips through JSON (:meth:`to_dict`, :meth:`from_dict`)."""

    ARRAYS: ClassVar[tuple[str, ...]] = ()
    joint_names: tuple[str, ...] = field(default=(), kw_only=True)
    method: str = field(default="", kw_only=True)
    info: dict = field(default_factory=dict, repr=False, kw_only=True)

    @property
    def n(self) -> int:
        return getattr(self, self.ARRAYS[0]).shape[0]

    def to_dict(self) -> dict:
        return {"method": self.method, "joints": list(self.joint_names),
                **{name: getattr(self, name).tolist() for name in self.ARRAYS}, "info": self.info}

    @classmethod
    def from_dict(cls, d: dict):
        return cls(*(d.get(name) for name in cls.ARRAYS), joint_names=tuple(d.get("joints", ())),
                   method=d.get("method", ""), info=d.get("info", {}))


@dataclass
class MotorModel(_JointwiseModel):
    """Δq = Kτ τ + Kv q̇ + Kc sgn(q̇), one entry per joint."""

    ARRAYS: ClassVar[tuple[str, ...]] = ("k_tau", "k_v", "k_c")
    k_tau: np.ndarray
    k_v: np.ndarray
    k_c: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.k_tau = np.atleast_1d(np.asarray(self.k_tau, dtype=float))
        n = self.k_tau.size
        self.k_v = _per_joint(self.k_v, n)
        self.k_c = np.zeros(n) if self.k_c is None else _per_joint(self.k_c, n)
        self.joint_names = joint_names_or_default(self.joint_names, n, "actuator parameters")

    def delta_q(self, tau, dq, coulomb: bool = True) -> np.ndarray:
        """Command offset Δq for joint torque ``tau`` at velocity ``dq`` (arrays (N, n) or (n,))."""
        tau, dq = np.asarray(tau, float), np.asarray(dq, float)
        out = self.k_tau * tau + self.k_v * dq
        return out + self.k_c * _sgn(dq) if coulomb else out

    def torque(self, delta_q, dq, coulomb: bool = True) -> np.ndarray:
        """Inverse model: torque τ = (Δq − Kv q̇ − Kc sgn q̇) / Kτ."""
        delta_q, dq = np.asarray(delta_q, float), np.asarray(dq, float)
        r = delta_q - self.k_v * dq - (self.k_c * _sgn(dq) if coulomb else 0.0)
        return r / self.k_tau

    def over_estimation_fraction(self, tau, dq, delta_q, coulomb: bool = True) -> np.ndarray:
        tau, dq, delta_q = _log_columns(self.n, tau, dq, delta_q)
        return over_estimation_fraction(self.delta_q(tau, dq, coulomb), delta_q)


@dataclass
class CurrentModel(_JointwiseModel):
    """τ = K1 i − Fv q̇ − Fc sgn(q̇): torque from measured motor current, one entry per joint."""

    ARRAYS: ClassVar[tuple[str, ...]] = ("k1", "fv", "fc")
    k1: np.ndarray
    fv: np.ndarray
    fc: np.ndarray

    def __post_init__(self) -> None:
        self.k1 = np.atleast_1d(np.asarray(self.k1, float))
        n = self.k1.size
        self.fv = _per_joint(self.fv, n)
        self.fc = _per_joint(self.fc, n)
        self.joint_names = joint_names_or_default(self.joint_names, n)

    def torque(self, current, dq) -> np.ndarray:
        return self.k1 * np.asarray(current, float) - self.fv * np.asarray(dq, float) - self.fc * _sgn(dq)

    def current(self, tau, dq) -> np.ndarray:
        return (np.asarray(tau, float) + self.fv * np.asarray(dq, float) + self.fc * _sgn(dq)) / self.k1


@dataclass
class PiecewiseLinearModel(_JointwiseModel):
    """Per joint and per sign of q̇ (index 0: q̇ ≥ 0, 1: q̇ < 0) a continuous three-segment
    function of τ plus a velocity term:

        Δq = c + s_mid τ + (s_left − s_mid) min(0, τ − b1) + (s_right − s_mid) max(0, τ − b2) + Kv q̇

    Arrays have shape (n_joints, 2): ``c``, ``s_left``, ``s_mid``, ``s_right``, ``b1``, ``b2``, ``k_v``.
    """

    ARRAYS: ClassVar[tuple[str, ...]] = ("c", "s_left", "s_mid", "s_right", "b1", "b2", "k_v")
    c: np.ndarray
    s_left: np.ndarray
    s_mid: np.ndarray
    s_right: np.ndarray
    b1: np.ndarray
    b2: np.ndarray
    k_v: np.ndarray
    method: str = field(default="piecewise_linear", kw_only=True)

    def __post_init__(self) -> None:
        for name in self.ARRAYS:
            setattr(self, name, np.asarray(getattr(self, name), float).reshape(-1, 2))
        self.joint_names = joint_names_or_default(self.joint_names, self.n)

    def delta_q(self, tau, dq) -> np.ndarray:
        tau, dq = np.asarray(tau, float), np.asarray(dq, float)
        k = np.where(dq >= 0, 0, 1)
        j = np.arange(self.n)
        p = {name: getattr(self, name)[j, k] for name in self.ARRAYS}
        return (p["c"] + p["s_mid"] * tau + (p["s_left"] - p["s_mid"]) * np.minimum(0.0, tau - p["b1"])
                + (p["s_right"] - p["s_mid"]) * np.maximum(0.0, tau - p["b2"]) + p["k_v"] * dq)

    def over_estimation_fraction(self, tau, dq, delta_q) -> np.ndarray:
        tau, dq, delta_q = _log_columns(self.n, tau, dq, delta_q)
        return over_estimation_fraction(self.delta_q(tau, dq), delta_q)

    def to_dict(self) -> dict:
        return {**super().to_dict(), "sign_order": ["dq>=0", "dq<0"]}

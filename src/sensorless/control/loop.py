"""The whole controller of a position-controlled robot, one tick at a time.

Sensors → causal Savitzky–Golay velocity/acceleration of the encoders → τ̂ from F/T + IMU
(:class:`~sensorless.estimation.joint_torque.JointTorqueEstimator`) → τ_d (inverse
dynamics, :class:`.InverseDynamics`) → τ* and Δq (:class:`.JointTorqueController`) →
q_cmd for the drives. Also :class:`StreamingSavgol`, the real-time filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..actuator.model import MotorModel
from ..data.filtering import SavitzkyGolay
from ..errors import DataError
from ..estimation.joint_torque import JointTorqueEstimator
from .gains import TorqueGains
from .inverse_dynamics import InverseDynamics, contact_wrench_from_ft
from .torque_controller import JointTorqueController

__all__ = ["ContactSpec", "Reference", "StreamingSavgol", "TorqueControlLoop"]


class StreamingSavgol:
    """Causal Savitzky–Golay on a ring buffer: smoothed value and derivatives at the newest
    sample (coefficients precomputed by :class:`~sensorless.data.SavitzkyGolay` with
    ``causal=True``; exact and delay-free on polynomials of degree ≤ ``polyorder``). The
    buffer starts filled with the first sample (zero derivatives during warm-up)."""

    def __init__(self, window: int, polyorder: int, dt: float, width: int) -> None:
        self.sg = SavitzkyGolay(window, polyorder, dt, causal=True)
        self.c = np.array([self.sg.coeffs[d] for d in range(min(polyorder, 2) + 1)])  # (3, w) oldest first
        self.buf = None
        self.width = width

    def reset(self) -> None:
        self.buf = None

    def push(self, x: np.ndarray) -> np.ndarray:
        """Append ``x`` (width,) and return (derivs, width): value, d/dt, d²/dt²."""
        x = np.asarray(x, float)
        if self.buf is None:
            self.buf = np.tile(x, (self.sg.window, 1))
        else:
            self.buf[:-1] = self.buf[1:]
            self.buf[-1] = x
        return self.c @ self.buf


@dataclass
class Reference:
    """Desired joint trajectory (N, n) sampled at the control rate, optional desired contact wrench (N, 6)."""

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    f: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not (self.q.shape == self.dq.shape == self.ddq.shape):
            raise DataError(f"reference q, dq, ddq shapes differ: {self.q.shape}, {self.dq.shape}, {self.ddq.shape}")

    def __len__(self) -> int:
        return self.q.shape[0]

    def at(self, k: int):
        k = min(k, len(self) - 1)
        return self.q[k], self.dq[k], self.ddq[k], None if self.f is None else self.f[k]


@dataclass
class ContactSpec:
    ft_frame: str
    contact_frame: str
    distal_inertia: pin.Inertia | None = None


@dataclass
class TorqueControlLoop:
    """Callable ``(k, reading) -> q_cmd`` for a simulated leg's ``simulate`` (the studies package:
    ``simulation.position_controlled``).

    ``reading`` must have ``q``, ``ft``, ``gyro``, ``acc``. ``feedback=False`` zeroes every
    feedback term (Kp, Ki, Ks, Kd, Kf): pure feedforward through the motor model.
    Intermediate signals are kept in :attr:`trace` (τ_d, τ̂, f̂).
    """

    estimator: JointTorqueEstimator
    motor: MotorModel
    gains: TorqueGains
    reference: Reference
    dt: float = 1e-3
    contact: ContactSpec | None = None
    velocity_window: int = 15
    acceleration_window: int = 31
    feedback: bool = True
    coulomb: bool = False
    trace: dict = field(default_factory=lambda: {"tau_d": [], "tau_hat": [], "f_hat": []})

    def __post_init__(self) -> None:
        robot = self.estimator.robot
        self.robot = robot
        self.id = InverseDynamics(robot, self.contact.contact_frame if self.contact else None)
        g = self.gains
        zero = np.zeros_like(g.kp)
        self.jtc = JointTorqueController(self.motor, g.kp if self.feedback else zero, g.ki if self.feedback else zero,
                                         self.dt, coulomb=self.coulomb)
        n = len(robot.joint_names)
        self.fv = StreamingSavgol(self.velocity_window, 2, self.dt, n)
        self.fa = StreamingSavgol(self.acceleration_window, 2, self.dt, n)

    def reset(self) -> None:
        self.fv.reset()
        self.fa.reset()
        self.jtc.reset()
        for v in self.trace.values():
            v.clear()

    def __call__(self, k: int, reading) -> np.ndarray:
        q_d, dq_d, ddq_d, f_d = self.reference.at(k)
        if reading is None:
            return np.array(q_d, float)
        q = reading.q
        dq = self.fv.push(q)[1]
        ddq = self.fa.push(q)[2]
        tau_hat = self.estimator.step(q, dq, ddq, [reading.ft], reading.gyro, reading.acc)[0]
        g = self.gains
        f_hat = None
        if self.contact is not None and f_d is not None:
            c = self.contact
            f_hat = contact_wrench_from_ft(self.robot, q, reading.ft, c.ft_frame, c.contact_frame, c.distal_inertia)
        if self.feedback:
            tau_d, _ = self.id.torque(q, dq, q_d, dq_d, ddq_d, g.ks, g.kd, f_d, f_hat, g.kf)
        else:
            tau_d = self.id.feedforward(q, dq, ddq_d, f_d)
        self.trace["tau_d"].append(tau_d)
        self.trace["tau_hat"].append(tau_hat)
        self.trace["f_hat"].append(f_hat if f_hat is not None else np.zeros(6))
        return self.jtc.command(q, dq, tau_d, tau_hat)

"""Joint torque feedback through a position-controlled drive.

    τ* = τ_d + Kp (τ_d − τ̂) + Ki ∫(τ_d − τ̂) dt          (integral clamped to ± ``integral_limit``)
    Δq = Kτ τ* + Kv q̇ (+ Kc sgn q̇)                       (inverse of the identified motor model)
    q_cmd = q + Δq

The joint then produces τ ≈ τ* if the motor model is right; the feedback on the estimated
torque τ̂ (F/T + IMU, :mod:`sensorless.estimation.joint_torque`) corrects the model error.
With a stiff drive the torque follows Δq within one tick, so the discrete loop has a pole
near −Kp·Kτ_true/Kτ_model: keep Kp well below 1 unless the drive is slow.
"""

from __future__ import annotations

import numpy as np

from ..actuator.model import MotorModel
from ..errors import DataError

__all__ = ["JointTorqueController"]


class JointTorqueController:
    def __init__(self, motor: MotorModel, kp, ki=0.0, dt: float = 1e-3, integral_limit=None, coulomb: bool = False) -> None:
        n = motor.n
        self.motor = motor
        self.kp = np.broadcast_to(np.asarray(kp, float), (n,)).copy()
        self.ki = np.broadcast_to(np.asarray(ki, float), (n,)).copy()
        if not (np.isfinite(dt) and dt > 0):
            raise DataError(f"dt must be positive, got {dt}")
        self.dt = float(dt)
        self.integral_limit = None if integral_limit is None else np.broadcast_to(np.asarray(integral_limit, float), (n,))
        self.coulomb = coulomb
        self.reset()

    def reset(self) -> None:
        self.integral = np.zeros(self.motor.n)

    def tau_star(self, tau_d, tau_hat) -> np.ndarray:
        err = np.asarray(tau_d, float) - np.asarray(tau_hat, float)
        if np.any(self.ki):
            self.integral = self.integral + err * self.dt
            if self.integral_limit is not None:
                self.integral = np.clip(self.integral, -self.integral_limit, self.integral_limit)
        return np.asarray(tau_d, float) + self.kp * err + self.ki * self.integral

    def delta_q(self, tau_d, tau_hat, dq) -> np.ndarray:
        return self.motor.delta_q(self.tau_star(tau_d, tau_hat), dq, coulomb=self.coulomb)

    def command(self, q, dq, tau_d, tau_hat) -> np.ndarray:
        return np.asarray(q, float) + self.delta_q(tau_d, tau_hat, dq)

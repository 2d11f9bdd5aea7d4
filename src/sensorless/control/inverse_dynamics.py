"""Inverse dynamics with joint-space PD and contact-force feedback (Pinocchio).

    τ_d = M(q) q̈_d + h(q, q̇) − Jᵀ f* + Ks e_q + Kd ė_q,     f* = f_d + Kf (f_d − f̂)

M from ``pin.crba`` (upper triangle symmetrised), h = C q̇ + g from
``pin.nonLinearEffects``, J the 6 × nv Jacobian of the contact frame (``pin
.computeFrameJacobian``, default axes LOCAL_WORLD_ALIGNED: wrenches [f; m] at the frame
origin in world axes). f is the wrench the environment applies on the robot, so that at
rest the robot obtains f = f_d with τ = h − Jᵀ f_d.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import RobotModelError, ShapeMismatchError
from ..estimation.force import REFERENCES
from ..robot import Robot

__all__ = ["InverseDynamics", "contact_wrench_from_ft"]


class InverseDynamics:
    """τ_d for a fixed-base robot whose joints are all actuated (``robot.joint_names`` order)."""

    def __init__(self, robot: Robot, contact_frame: str | None = None, reference: str = "local_world_aligned",
                 include_armature: bool = False) -> None:
        if robot.floating_base:
            raise RobotModelError("InverseDynamics: fixed-base robots only (use a whole-body controller for floating bases)")
        self.robot = robot
        self.model = robot.model.copy()
        if not include_armature:
            self.model.armature[:] = 0.0
        self.data = self.model.createData()
        self.contact_frame = contact_frame
        self._fid = robot.frame_id(contact_frame) if contact_frame else None
        try:
            self._ref = REFERENCES[reference.lower()]
        except KeyError:
            raise RobotModelError(f"unknown reference '{reference}'; choose from {sorted(REFERENCES)}") from None
        self._idx = np.array([robot.v_index(n) for n in robot.joint_names])
        if robot.nq != robot.nv or not np.array_equal(self._idx, np.arange(robot.nv)):
            self._q_full = lambda q: robot.full_configuration(np.asarray(q)[None])[0]
        else:
            self._q_full = lambda q: np.asarray(q, float)

    def mass_matrix(self, q) -> np.ndarray:
        M = pin.crba(self.model, self.data, self._q_full(q))
        return np.triu(M) + np.triu(M, 1).T

    def jacobian(self, q) -> np.ndarray:
        if self._fid is None:
            raise RobotModelError("no contact frame was given to InverseDynamics")
        return pin.computeFrameJacobian(self.model, self.data, self._q_full(q), self._fid, self._ref)

    def feedforward(self, q, dq, ddq_d, f_d=None) -> np.ndarray:
        """τ_ff = M q̈_d + h − Jᵀ f_d (equals ``pin.rnea`` when f_d = 0)."""
        q = np.asarray(q, float)
        dq, ddq_d = np.asarray(dq, float), np.asarray(ddq_d, float)
        if dq.shape != (self.robot.nv,) or ddq_d.shape != (self.robot.nv,):
            raise ShapeMismatchError(f"dq and ddq_d must have {self.robot.nv} entries")
        tau = self.mass_matrix(q) @ ddq_d + pin.nonLinearEffects(self.model, self.data, self._q_full(q), dq)
        if f_d is not None:
            tau = tau - self.jacobian(q).T @ np.asarray(f_d, float)
        return tau

    def torque(self, q, dq, q_d, dq_d, ddq_d, ks, kd, f_d=None, f_meas=None, kf=0.0) -> tuple[np.ndarray, np.ndarray | None]:
        """(τ_d, f*). ``f_meas`` is needed when ``kf`` ≠ 0."""
        f_star = None
        if f_d is not None:
            f_d = np.asarray(f_d, float)
            f_star = f_d.copy()
            if f_meas is not None:
                f_star = f_d + np.asarray(kf, float) * (f_d - np.asarray(f_meas, float))
        e = np.asarray(q_d, float) - np.asarray(q, float)
        de = np.asarray(dq_d, float) - np.asarray(dq, float)
        tau = self.feedforward(q, dq, ddq_d, f_star) + np.asarray(ks) * e + np.asarray(kd) * de
        return tau, f_star


def contact_wrench_from_ft(robot: Robot, q, ft, ft_frame: str, contact_frame: str, distal_inertia: pin.Inertia | None,
                           gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)) -> np.ndarray:
    """Wrench of the environment on the robot at ``contact_frame`` (LOCAL_WORLD_ALIGNED) from
    an F/T reading (distal on proximal, sensor frame), neglecting the distal part's
    acceleration (a foot standing on the ground) but not its weight."""
    m, d = robot.model, robot.data
    pin.framesForwardKinematics(m, d, robot.full_configuration(np.asarray(q, float)[None])[0])
    oMs = d.oMf[robot.frame_id(ft_frame)]
    oMc = d.oMf[robot.frame_id(contact_frame)]
    w = pin.Force(np.asarray(ft, float))
    if distal_inertia is not None:
        g_s = oMs.rotation.T @ np.asarray(gravity, float)
        fg = distal_inertia.mass * g_s
        w = w - pin.Force(fg, np.cross(distal_inertia.lever, fg))
    # w: environment wrench at the sensor frame; express at the contact point, world axes
    cMs = pin.SE3(oMc.rotation, oMc.translation).inverse() * oMs
    w_c = cMs.act(w)
    R = oMc.rotation
    return np.r_[R @ w_c.linear, R @ w_c.angular]

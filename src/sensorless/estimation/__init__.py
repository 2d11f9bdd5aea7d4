"""Estimation from sensors and identified models: joint torque from F/T + IMU + encoders,
external joint torque and Cartesian force."""

from .contact_forces import estimate_contact_forces
from .force import CartesianForceEstimator, damped_least_squares, external_torque, frame_jacobians
from .joint_torque import JointTorqueEstimator
from .monitoring import MonitorSettings, monitor_log
from .momentum import MomentumDynamics, MomentumObserver

__all__ = [
    "CartesianForceEstimator",
    "JointTorqueEstimator",
    "MomentumDynamics",
    "MonitorSettings",
    "MomentumObserver",
    "damped_least_squares",
    "estimate_contact_forces",
    "external_torque",
    "frame_jacobians",
    "monitor_log",
]

"""Estimation from sensors and identified models: joint torque from F/T + IMU + encoders,
external joint torque and Cartesian force."""

from .force import (
    REFERENCES,
    CartesianForceEstimator,
    ForceEstimate,
    damped_least_squares,
    external_torque,
    frame_jacobians,
)
from .joint_torque import FTSensor, ImuSpec, JointTorqueEstimate, JointTorqueEstimator

__all__ = [
    "REFERENCES",
    "CartesianForceEstimator",
    "FTSensor",
    "ForceEstimate",
    "ImuSpec",
    "JointTorqueEstimate",
    "JointTorqueEstimator",
    "damped_least_squares",
    "external_torque",
    "frame_jacobians",
]

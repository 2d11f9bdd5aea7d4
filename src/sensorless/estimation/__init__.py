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
from .momentum import MomentumDynamics, MomentumObserver, ObserverResult, depth_first_model, observer_filter

__all__ = [
    "REFERENCES",
    "CartesianForceEstimator",
    "FTSensor",
    "ForceEstimate",
    "ImuSpec",
    "JointTorqueEstimate",
    "JointTorqueEstimator",
    "MomentumDynamics",
    "MomentumObserver",
    "ObserverResult",
    "damped_least_squares",
    "depth_first_model",
    "external_torque",
    "frame_jacobians",
    "observer_filter",
]

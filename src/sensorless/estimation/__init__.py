"""Estimation from sensors and identified models: joint torque from F/T + IMU + encoders,
external joint torque and Cartesian force."""

from .collision import ContactInterval, Thresholds, detect_contacts, quiet_mask, quiet_thresholds, score_detection
from .contact_forces import ContactForceEstimate, estimate_contact_forces, solve_contact_forces
from .force import (
    REFERENCES,
    CartesianForceEstimator,
    ForceEstimate,
    damped_least_squares,
    external_torque,
    frame_jacobians,
)
from .joint_torque import FTSensor, ImuSpec, JointTorqueEstimate, JointTorqueEstimator
from .momentum import (
    MomentumDynamics,
    MomentumObserver,
    ObserverResult,
    benchmark_observer,
    depth_first_model,
    observer_filter,
)

__all__ = [
    "REFERENCES",
    "benchmark_observer",
    "CartesianForceEstimator",
    "ContactForceEstimate",
    "ContactInterval",
    "FTSensor",
    "ForceEstimate",
    "ImuSpec",
    "JointTorqueEstimate",
    "JointTorqueEstimator",
    "MomentumDynamics",
    "MomentumObserver",
    "ObserverResult",
    "Thresholds",
    "damped_least_squares",
    "depth_first_model",
    "detect_contacts",
    "estimate_contact_forces",
    "external_torque",
    "frame_jacobians",
    "observer_filter",
    "quiet_mask",
    "quiet_thresholds",
    "score_detection",
    "solve_contact_forces",
]

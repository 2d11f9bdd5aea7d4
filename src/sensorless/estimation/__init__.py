"""Estimation from sensors and identified models: joint torque from F/T + IMU + encoders,
external joint torque and Cartesian force."""

from .collision import (
    ContactInterval,
    Thresholds,
    detect_contacts,
    observer_warmup,
    quiet_mask,
    quiet_thresholds,
    score_detection,
)
from .contact_stream import ContactStream
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
from .monitoring import MonitorResult, MonitorSettings, monitor_log
from .static_band import StaticFriction, model_static_friction
from .momentum import (
    MomentumDynamics,
    MomentumObserver,
    ObserverResult,
    depth_first_model,
)

__all__ = [
    "REFERENCES",
    "CartesianForceEstimator",
    "ContactForceEstimate",
    "ContactInterval",
    "ContactStream",
    "FTSensor",
    "ForceEstimate",
    "ImuSpec",
    "JointTorqueEstimate",
    "JointTorqueEstimator",
    "MomentumDynamics",
    "MonitorResult",
    "MonitorSettings",
    "MomentumObserver",
    "ObserverResult",
    "StaticFriction",
    "Thresholds",
    "damped_least_squares",
    "depth_first_model",
    "detect_contacts",
    "estimate_contact_forces",
    "external_torque",
    "frame_jacobians",
    "model_static_friction",
    "monitor_log",
    "observer_warmup",
    "quiet_mask",
    "quiet_thresholds",
    "score_detection",
    "solve_contact_forces",
]

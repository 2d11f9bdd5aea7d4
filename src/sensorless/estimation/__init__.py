"""Estimation from sensors and identified models: joint torque from F/T + IMU + encoders."""

from .joint_torque import FTSensor, ImuSpec, JointTorqueEstimate, JointTorqueEstimator

__all__ = ["FTSensor", "ImuSpec", "JointTorqueEstimate", "JointTorqueEstimator"]

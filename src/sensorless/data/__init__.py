"""Logs in, clean trajectories out: readers, validation, filtering and resampling."""

from __future__ import annotations

from .filtering import SavitzkyGolay, butter_lowpass, decimate, lowpass, resample_uniform, savgol_derivatives, trim
from .integral_filter import LowpassChain, observer_filter
from .imu import base_acceleration, imu_base_acceleration
from .readers import read_trajectory, write_npz
from .trajectory import Trajectory
from .validation import validate_trajectory

__all__ = [
    "LowpassChain",
    "observer_filter",
    "Trajectory",
    "read_trajectory",
    "write_npz",
    "validate_trajectory",
    "lowpass",
    "butter_lowpass",
    "SavitzkyGolay",
    "savgol_derivatives",
    "trim",
    "decimate",
    "resample_uniform",
    "base_acceleration",
    "imu_base_acceleration",
]

"""Logs in, clean trajectories out: readers, validation, filtering and resampling."""

from __future__ import annotations

from .filtering import SavitzkyGolay, butter_lowpass, decimate, lowpass, resample_uniform, savgol_derivatives, trim
from .imu import base_acceleration, imu_base_acceleration
from .outliers import check_outliers, drop_outliers, find_outliers, handle_outliers
from .readers import read_trajectory, write_npz
from .trajectory import Trajectory
from .validation import validate_trajectory

__all__ = [
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
    "find_outliers",
    "check_outliers",
    "drop_outliers",
    "handle_outliers",
]

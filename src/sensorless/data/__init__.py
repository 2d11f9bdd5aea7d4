"""Logs in, clean trajectories out: readers, validation, filtering and resampling."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

from .align import pair_logs
from .filtering import (
    SavitzkyGolay,
    butter_lowpass,
    decimate,
    default_savgol_window,
    lowpass,
    resample_uniform,
    savgol_derivatives,
    trim,
)
from .prepare import prepare
from .trims import LogTrims, TrimWindow, trim_window
from .readers import read_trajectory, write_npz
from .resample import resample, timing
from .trajectory import Trajectory
from .validation import validate_trajectory
from .wrench_frames import express_wrenches

# The modules that load SciPy's interpolation/signal packages or Pinocchio are imported on first use
_EXPORTS = {
    "clean_base_pose": ".base_pose",
    **dict.fromkeys(["base_acceleration", "imu_base_acceleration", "imu_frame_base_acceleration"], ".imu"),
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from .base_pose import clean_base_pose
    from .imu import base_acceleration, imu_base_acceleration, imu_frame_base_acceleration

__all__ = [
    "pair_logs",
    "default_savgol_window",
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
    "prepare",
    "TrimWindow",
    "LogTrims",
    "trim_window",
    "resample",
    "timing",
    "imu_frame_base_acceleration",
    "clean_base_pose",
    "express_wrenches",
]

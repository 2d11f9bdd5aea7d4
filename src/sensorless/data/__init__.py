"""Logs in, clean trajectories out: readers, validation, filtering and resampling."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

from .align import Pairing, clock_offset, estimate_lag, pair_logs
from .filtering import SavitzkyGolay, butter_lowpass, decimate, lowpass, lowpass_channels, resample_uniform, savgol_derivatives, trim
from .gains import currents_to_torques, load_gains, resolve_gains
from .prepare import prepare
from .filtering import default_savgol_window
from .trims import LogTrims, TrimWindow, trim_window
from .rest import rest_mask, zero_at_rest
from .outliers import check_outliers, drop_outliers, find_outliers, handle_outliers
from .readers import read_trajectory, write_npz
from .resample import Timing, resample, timing
from .rosbag import is_rosbag, read_rosbag
from .trajectory import Trajectory
from .validation import validate_trajectory
from .wrench_frames import express_wrenches, wrench_frame_map

# The modules that load SciPy's interpolation/signal packages or Pinocchio are imported on first use
_EXPORTS = {
    **dict.fromkeys(["BasePose", "clean_base_pose", "with_base_pose", "clip_to_pose", "base_motion_from_pose"],
                    ".base_pose"),
    **dict.fromkeys(["base_acceleration", "imu_base_acceleration", "imu_frame_base_acceleration"], ".imu"),
    **dict.fromkeys(["LowpassChain", "observer_filter"], ".integral_filter"),
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from .base_pose import BasePose, base_motion_from_pose, clean_base_pose, clip_to_pose, with_base_pose
    from .imu import base_acceleration, imu_base_acceleration, imu_frame_base_acceleration
    from .integral_filter import LowpassChain, observer_filter

__all__ = [
    "Pairing",
    "clock_offset",
    "estimate_lag",
    "pair_logs",
    "default_savgol_window",
    "rest_mask",
    "zero_at_rest",
    "LowpassChain",
    "observer_filter",
    "Trajectory",
    "read_trajectory",
    "read_rosbag",
    "is_rosbag",
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
    "Timing",
    "currents_to_torques",
    "load_gains",
    "resolve_gains",
    "imu_frame_base_acceleration",
    "BasePose",
    "clean_base_pose",
    "with_base_pose",
    "clip_to_pose",
    "base_motion_from_pose",
    "express_wrenches",
    "wrench_frame_map",
    "lowpass_channels",
    "find_outliers",
    "check_outliers",
    "drop_outliers",
    "handle_outliers",
]

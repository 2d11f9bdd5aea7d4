"""ROS 1 bags, ROS 2 bag folders and MCAP / .db3 files (:mod:`..rosbag`): topics instead of columns,
read straight to a validated Trajectory."""

from __future__ import annotations

from pathlib import Path

from ...errors import DataError
from ..rosbag import ROSBAG_SUFFIXES, is_rosbag, read_rosbag, rosbag_options
from ..trajectory import Trajectory
from .base import LogFormat

__all__ = ["ROSBAG"]


def read_bag(path: Path, columns, joint_names, *, robot=None, gains=None, rate=None, time_unit=None,
             angle_unit="rad", allow_duplicate_times=False, outliers="error", **rows) -> Trajectory:
    """The validated Trajectory of a bag; ``columns`` names its topics (:func:`..rosbag.rosbag_options`)."""
    src = str(path)
    if gains is not None or rate is not None or time_unit is not None or angle_unit != "rad":
        raise DataError("gains, rate, time_unit and angle_unit do not apply to a ROS bag (its stamps are in "
                        "seconds, its joint positions in radians)", src)
    return read_rosbag(path, joint_names=joint_names, robot=robot, allow_duplicate_times=allow_duplicate_times,
                       outliers=outliers, **rows, **rosbag_options(columns, src))


ROSBAG = LogFormat("rosbag", "ROS .bag / .mcap / ROS 2 bag folder", suffixes=ROSBAG_SUFFIXES, items="topics",
                   trajectory=True, claims=is_rosbag, reader=read_bag)

"""ROS 1 bags, ROS 2 bag folders and MCAP / .db3 files (:mod:`..rosbag`): topics instead of columns,
read straight to a validated Trajectory."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ...errors import DataError
from ..rosbag import ROSBAG_SUFFIXES, is_rosbag, read_rosbag, rosbag_options
from ..trajectory import Trajectory

__all__ = ["RosBag"]


@dataclass(frozen=True)
class RosBag:
    name = "rosbag"
    suffixes = ROSBAG_SUFFIXES
    description = "ROS .bag / .mcap / ROS 2 bag folder"
    items = "topics"
    arrays = False
    trajectory = True

    def sniff(self, path: Path) -> bool:
        return is_rosbag(path)

    def read(self, path: Path, columns, joint_names, *, robot=None, gains=None, rate=None, time_unit=None,
             angle_unit="rad", allow_duplicate_times=False, outliers="error", **rows) -> Trajectory:
        src = str(path)
        if gains is not None or rate is not None or time_unit is not None or angle_unit != "rad":
            raise DataError("gains, rate, time_unit and angle_unit do not apply to a ROS bag (its stamps are in "
                            "seconds, its joint positions in radians)", src)
        return read_rosbag(path, joint_names=joint_names, robot=robot, allow_duplicate_times=allow_duplicate_times,
                           outliers=outliers, **rows, **rosbag_options(columns, src))

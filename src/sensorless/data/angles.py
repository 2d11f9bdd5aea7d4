"""Joint angles logged in degrees: ``angle_unit="deg"`` converts them to radians on reading.

q [deg] → q·π/180 [rad], and v, v̇ likewise [deg/s, deg/s²], on the revolute joints of the robot
(every joint when no robot is given; a prismatic joint's metres are left alone). The conversion is
recorded in ``units["angles"]``, and ``angle_unit`` in a model's ``settings.preprocessing`` so that
``predict`` and the other commands that apply it read new logs the same way.
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError, setting
from .trajectory import Trajectory

__all__ = ["ANGLE_UNITS", "check_angle_unit", "to_radians"]

ANGLE_UNITS = ("rad", "deg")


def check_angle_unit(angle_unit: str | None, src: str | None = None) -> str:
    """``angle_unit`` ("rad" when None); DataError for another value."""
    unit = "rad" if angle_unit is None else str(angle_unit).strip().lower()
    if unit not in ANGLE_UNITS:
        raise DataError(f"{setting('angle_unit')} must be one of {', '.join(ANGLE_UNITS)}, got {angle_unit!r}", src)
    return unit


def to_radians(traj: Trajectory, angle_unit: str | None, robot=None) -> Trajectory:
    """``traj`` with q, v and v̇ of its revolute joints converted from degrees when ``angle_unit``
    is "deg" (module docstring); unchanged for "rad" or None."""
    if check_angle_unit(angle_unit, traj.source) == "rad":
        return traj
    names = list(traj.joint_names)
    revolute = [j for j, n in enumerate(names)
                if robot is None or n not in robot.joint_names or robot.is_revolute(n)]
    scale = np.ones(len(names))
    scale[revolute] = np.pi / 180.0
    fields = {k: np.asarray(getattr(traj, k), dtype=float) * scale
              for k in ("q", "v", "a") if getattr(traj, k) is not None}
    note = f"deg → rad on {len(revolute)} of {len(names)} joints" + (
        "" if len(revolute) == len(names) else
        f" (not the prismatic {', '.join(n for j, n in enumerate(names) if j not in revolute)})")
    return traj.with_(**fields, units={**traj.units, "angles": note})

"""The registry of named robots: every name :func:`sensorless.robot.load_robot` accepts besides a model
file (URDF, xacro, MJCF), in the way of robot_descriptions.

To add a robot: a description a package ships (an entry whose ``load`` returns its Pinocchio model), or
a robot built in code (its module in this package and a :class:`~.base.CodeRobot` line pointing at its
builder); one line in :data:`ROBOTS`; one oracle test (``tests/test_robots_registry.py``: it loads by
name and equals the model built directly).
"""

from __future__ import annotations

from .base import CodeRobot, RobotEntry
from .erd_robots import ExampleRobotData

__all__ = ["ROBOTS", "find_robot", "robot_names"]

ROBOTS: tuple[RobotEntry, ...] = (
    CodeRobot(("dvrk_psm", "dvrk-psm", "psm"), "sensorless.robots.dvrk_psm:psm_robot",
              "the dVRK PSM, a coupled-joint model in motor coordinates", coupled=True),
    ExampleRobotData(),
)


def find_robot(name: str) -> "RobotEntry | None":
    """The first entry of :data:`ROBOTS` that matches ``name``; None when none does."""
    return next((e for e in ROBOTS if e.matches(str(name))), None)


def robot_names() -> list[str]:
    """Every registered name (the robots built in code first), for messages and help."""
    return [n for e in ROBOTS for n in e.names]

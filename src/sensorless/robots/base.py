"""What a named robot is: an entry of the registry :mod:`.registry` that ``load_robot(name)`` consults.

An entry declares the ``names`` it answers to (or ``matches`` a family of names), a one-line
``description``, and capabilities:

* ``in_code``: ``load`` returns the robot itself, built in code (no model file); the load options of a
  model file (floating base, locked, actuated and passive joints, armature) do not apply to it;
  otherwise ``load`` returns the Pinocchio model of a description and :func:`~sensorless.robot.load_robot`
  applies those options;
* ``coupled``: joints driven through a transmission by other coordinates (e.g. motor coordinates of a
  cable-coupled wrist): the robot's identification structures come from ``robot.make_structure``, and
  it may declare its own excitation box (``robot.excitation_box``).

A robot built in code lives in its own module of this package (``dvrk_psm.py``) and is referred to by
its dotted path (``"sensorless.robots.dvrk_psm:psm_robot"``), imported only when it is loaded — as a
plugin or an entry point is: the registry sits at the layer of ``load_robot``, the robot's model code
above it (``tests/test_layers.py``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

__all__ = ["CodeRobot", "RobotEntry"]


@runtime_checkable
class RobotEntry(Protocol):
    """One registry entry (module docstring)."""

    names: tuple[str, ...]
    description: str
    in_code: bool
    coupled: bool

    def matches(self, name: str) -> bool:
        """True when ``name`` is this entry's."""
        ...

    def load(self, name: str, floating_base: "bool | None" = None) -> Any:
        """``in_code``: the robot; else (Pinocchio model, robot name, source, URDF path or None)."""
        ...


@dataclass(frozen=True)
class CodeRobot:
    """A robot built in code by ``builder`` (``"package.module:function"``, called without arguments);
    ``names`` match case-insensitively."""

    names: tuple[str, ...]
    builder: str
    description: str
    coupled: bool = False
    in_code = True

    def matches(self, name: str) -> bool:
        return str(name).lower() in self.names

    def load(self, name: str, floating_base: "bool | None" = None) -> Any:
        module, _, function = self.builder.partition(":")
        return getattr(importlib.import_module(module), function)()

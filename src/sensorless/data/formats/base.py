"""What a log format is: ``sniff(path)`` (is this file mine?) and ``read`` (the fields it holds).

A format reads a file into a :class:`~sensorless.data.names.RawLog` (arrays by field, the joint
names it stores, the items no field used), which :func:`sensorless.data.read_trajectory`
assembles, converts and validates the same way for every format. Capability flags:

* ``items``: what the format's unused items are called in the reader's warning (columns, arrays, ...);
* ``arrays``: the file stores named arrays that may be channels × samples (:mod:`..orientation`);
* ``trajectory``: the format reads straight to a validated Trajectory with its own options (ROS bags:
  topics instead of columns); its ``read`` takes the reader's keyword arguments.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Protocol, Sequence, runtime_checkable

__all__ = ["LogFormat"]


@runtime_checkable
class LogFormat(Protocol):
    """One log format: its ``name``, the file ``suffixes`` it owns, a ``description`` for the help of
    ``--data``, the flags of the module docstring, ``sniff`` and ``read``."""

    name: str
    suffixes: tuple[str, ...]
    description: str
    items: str
    arrays: bool
    trajectory: bool

    def sniff(self, path: Path) -> bool:
        """True when ``path`` is a log of this format (by name or content; never reads it whole)."""
        ...

    def read(self, path: Path, columns: Mapping[str, Any] | None, joint_names: Sequence[str] | None) -> Any:
        """The fields of the log: a RawLog (or, for ``trajectory`` formats, the Trajectory)."""
        ...

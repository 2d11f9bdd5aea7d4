"""What a log format is: ``sniff(path)`` (is this file mine?) and ``read`` (the fields it holds).

A format reads a file into a :class:`~sensorless.data.names.RawLog` (arrays by field, the joint
names it stores, the items no field used), which :func:`sensorless.data.read_trajectory`
assembles, converts and validates the same way for every format. Capability flags:

* ``items``: what the format's unused items are called in the reader's warning (columns, arrays, ...);
* ``arrays``: the file stores named arrays that may be channels × samples (:mod:`..orientation`);
* ``trajectory``: the format reads straight to a validated Trajectory with its own options (ROS bags:
  topics instead of columns); its ``read`` takes the reader's keyword arguments.

A format claims the paths with one of its ``suffixes`` and those its ``claims`` test accepts (a MATLAB
v7.3 file named ``.h5``, a ROS 2 bag folder). It reads with one of: ``table`` (path → a pandas frame
and whether its first row named the columns; the columns are then mapped onto fields by
:func:`..tabular.fields_from_frame`, the same for every table format) or ``reader`` (path, columns →
RawLog; with ``trajectory``: path, columns, joint names and the reader's keyword arguments →
Trajectory).
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from ..tabular import fields_from_frame

__all__ = ["LogFormat"]


@dataclass(frozen=True)
class LogFormat:
    """One log format: its ``name``, a ``description`` for the help of ``--data``, the file ``suffixes``
    it owns, the flags of the module docstring (default: a table of columns) and how it is claimed
    (``claims``) and read (``table`` or ``reader``)."""

    name: str
    description: str
    _: KW_ONLY
    suffixes: tuple[str, ...] = ()
    items: str = "columns"
    arrays: bool = False
    trajectory: bool = False
    claims: Callable[[Path], bool] | None = None
    table: Callable[[Path], tuple[Any, bool]] | None = None
    reader: Callable[..., Any] | None = None

    def sniff(self, path: Path) -> bool:
        """True when ``path`` is a log of this format (by name or content; never reads it whole)."""
        return path.suffix.lower() in self.suffixes or (self.claims is not None and self.claims(path))

    def read(self, path: Path, columns: Mapping[str, Any] | None, joint_names: Sequence[str] | None,
             **options: Any) -> Any:
        """The fields of the log: a RawLog (or, for ``trajectory`` formats, the Trajectory)."""
        if self.table is not None:
            frame, header = self.table(path)
            return fields_from_frame(frame, str(path), columns, joint_names, header)
        if self.trajectory:
            return self.reader(path, columns, joint_names, **options)
        return self.reader(path, columns)

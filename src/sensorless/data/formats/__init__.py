"""The registry of log formats: one file per format with ``sniff(path)`` and ``read`` (:class:`~.base.LogFormat`).

:func:`sensorless.data.read_trajectory` asks the formats of :data:`FORMATS` in order whether a path is
theirs (:func:`find_format`) and reads it with the first that says yes; the command line's ``--data``
help lists them (:func:`formats_help`). Order matters where two formats could claim a path: a ROS 2
bag folder before a folder of per-signal files, a MATLAB v7.3 file before HDF5.

To add a format: one file here with a :class:`~.base.LogFormat` (name, description, suffixes, the flags
that differ from the defaults, and ``table`` or ``reader``), one line in :data:`FORMATS`, one oracle test
(the same log written in the new format and in a known one reads to the same Trajectory,
``tests/test_data_formats.py``).
"""

from __future__ import annotations

from pathlib import Path

from .arrow import ARROW
from .base import LogFormat
from .folder import FOLDER
from .hdf5 import HDF5
from .mat import MAT
from .npz import NPZ
from .parquet import PARQUET
from .rosbag import ROSBAG
from .text import TEXT

__all__ = ["FORMATS", "LogFormat", "SUPPORTED_EXTENSIONS", "find_format", "formats_help"]

FORMATS: tuple[LogFormat, ...] = (
    ROSBAG,
    FOLDER,
    TEXT,
    NPZ,
    PARQUET,
    MAT,
    HDF5,
    ARROW,
)
#: file suffix -> format name, the table formats first (the listing of an unsupported file's error)
SUPPORTED_EXTENSIONS: dict[str, str] = {s: f.name for f in sorted(FORMATS, key=lambda f: f.trajectory)
                                        for s in f.suffixes}


def find_format(path: str | Path) -> "LogFormat | None":
    """The first format of :data:`FORMATS` whose ``sniff`` claims ``path``; None when none does."""
    path = Path(path)
    return next((f for f in FORMATS if f.sniff(path)), None)


def formats_help() -> str:
    """The formats as the ``--data`` help lists them."""
    return ", ".join(f.description for f in FORMATS)

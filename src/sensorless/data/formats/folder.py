"""A folder of per-signal text files (``q.dat``, ``tau.dat``, ...; :mod:`..textlog`)."""

from __future__ import annotations

from pathlib import Path

from ..textlog import read_signal_folder
from .base import LogFormat

__all__ = ["FOLDER"]

FOLDER = LogFormat("folder", "a folder of per-signal text files", items="files", claims=Path.is_dir,
                   reader=read_signal_folder)

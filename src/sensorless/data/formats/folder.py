"""A folder of per-signal text files (``q.dat``, ``tau.dat``, ...; :mod:`..textlog`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..names import RawLog
from ..textlog import read_signal_folder

__all__ = ["SignalFolder"]


@dataclass(frozen=True)
class SignalFolder:
    name = "folder"
    suffixes = ()
    description = "a folder of per-signal text files"
    items = "files"
    arrays = False
    trajectory = False

    def sniff(self, path: Path) -> bool:
        return path.is_dir()

    def read(self, path: Path, columns, joint_names) -> RawLog:
        return read_signal_folder(path, columns)

"""NumPy ``.npz`` archives of named arrays (:func:`..arrays.read_npz`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..arrays import read_npz
from ..names import RawLog

__all__ = ["Npz"]


@dataclass(frozen=True)
class Npz:
    name = "npz"
    suffixes = (".npz",)
    description = ".npz"
    items = "arrays"
    arrays = True
    trajectory = False

    def sniff(self, path: Path) -> bool:
        return path.suffix.lower() in self.suffixes

    def read(self, path: Path, columns, joint_names) -> RawLog:
        return read_npz(path, columns)

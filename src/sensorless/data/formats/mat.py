"""MATLAB ``.mat`` files, v5 and v7.3 (:mod:`..matlab`); a v7.3 file saved as ``.h5``/``.hdf5`` too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..matlab import is_mat73, read_mat
from ..names import RawLog

__all__ = ["Mat"]


@dataclass(frozen=True)
class Mat:
    name = "mat"
    suffixes = (".mat",)
    description = ".mat"
    items = "variables"
    arrays = True
    trajectory = False

    def sniff(self, path: Path) -> bool:
        suffix = path.suffix.lower()
        return suffix in self.suffixes or (suffix in (".h5", ".hdf5") and is_mat73(path))

    def read(self, path: Path, columns, joint_names) -> RawLog:
        return read_mat(path, columns)

"""HDF5 files of datasets (``.h5 .hdf5``; :func:`..arrays.read_hdf5`). A MATLAB v7.3 file is HDF5 too:
:mod:`.mat` claims it first."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..arrays import read_hdf5
from ..names import RawLog

__all__ = ["Hdf5"]


@dataclass(frozen=True)
class Hdf5:
    name = "hdf5"
    suffixes = (".h5", ".hdf5")
    description = ".h5/.hdf5"
    items = "datasets"
    arrays = True
    trajectory = False

    def sniff(self, path: Path) -> bool:
        return path.suffix.lower() in self.suffixes

    def read(self, path: Path, columns, joint_names) -> RawLog:
        return read_hdf5(path, columns)

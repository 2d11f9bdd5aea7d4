"""HDF5 files of datasets (``.h5 .hdf5``; :func:`..arrays.read_hdf5`). A MATLAB v7.3 file is HDF5 too:
:mod:`.mat` claims it first."""

from __future__ import annotations

from ..arrays import read_hdf5
from .base import LogFormat

__all__ = ["HDF5"]

HDF5 = LogFormat("hdf5", ".h5/.hdf5", suffixes=(".h5", ".hdf5"), items="datasets", arrays=True, reader=read_hdf5)

"""NumPy ``.npz`` archives of named arrays (:func:`..arrays.read_npz`)."""

from __future__ import annotations

from ..arrays import read_npz
from .base import LogFormat

__all__ = ["NPZ"]

NPZ = LogFormat("npz", ".npz", suffixes=(".npz",), items="arrays", arrays=True, reader=read_npz)

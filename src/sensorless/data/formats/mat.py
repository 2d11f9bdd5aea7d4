"""MATLAB ``.mat`` files, v5 and v7.3 (:mod:`..matlab`); a v7.3 file saved as ``.h5``/``.hdf5`` too."""

from __future__ import annotations

from pathlib import Path

from ..matlab import is_mat73, read_mat
from .base import LogFormat

__all__ = ["MAT"]


def _mat73_as_hdf5(path: Path) -> bool:
    """A MATLAB v7.3 file saved as ``.h5``/``.hdf5``."""
    return path.suffix.lower() in (".h5", ".hdf5") and is_mat73(path)


MAT = LogFormat("mat", ".mat", suffixes=(".mat",), items="variables", arrays=True, claims=_mat73_as_hdf5,
                reader=read_mat)

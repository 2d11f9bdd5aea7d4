"""Streaming compression of the identification equations, wherever the logs are.

:func:`compress` folds trajectories in this process (:func:`~.normal_equations.compress_trajectories`:
the normal equations and how the fold is made fast are documented there) and log files, here or on
the workers of a Dask cluster (:func:`~.distributed.compress_files`).
"""

from __future__ import annotations

import os
from typing import Callable, Iterable

from ..data.trajectory import Trajectory
from .distributed import compress_files
from .normal_equations import NormalEquations, compress_trajectories
from .terms import ModelStructure

__all__ = ["compress"]


def _file_paths(data) -> bool:
    """``data`` names files (a path, a glob pattern, or a list/tuple of them) rather than trajectories."""
    if isinstance(data, (str, os.PathLike)):
        return True
    return isinstance(data, (list, tuple)) and any(isinstance(d, (str, os.PathLike)) for d in data)


def compress(
    structure: ModelStructure,
    data: Trajectory | Iterable[Trajectory],
    *,
    chunk: int = 2048,
    progress: Callable[[int], None] | None = None,
    client=None,
    reader=None,
    overlap: bool | None = None,
) -> NormalEquations:
    """Evaluate the regressor chunk by chunk and fold it into :class:`NormalEquations`.

    ``data`` may be a generator, so arbitrarily long logs never sit in memory whole.
    ``progress(n)`` is called with the number of samples folded after each chunk.

    ``data`` may also be file paths or glob patterns (a path, or a list of them): each file is
    read and preprocessed by ``reader`` (default :class:`~.distributed.LogReader`: the CLI's
    defaults) and folded, one after another in this process with ``client=None``, or by the
    workers of a Dask ``client`` (``distributed.Client``) that return partial sums added by a
    tree reduction (:func:`~.distributed.compress_files`; ``progress(1)`` per finished file). A
    file that cannot be used raises its typed error; to skip such files instead, use ``compress_files``.

    BLAS runs on one thread throughout; ``overlap`` folds chunk k in a helper thread while
    chunk k + 1 is evaluated (see :mod:`~.normal_equations`). ``None``: overlap when a core is idle
    (1-min load average below cores − 1); on a busy machine the thread only competes for the GIL.
    The sums do not depend on it (same folds, same order).
    """
    if client is not None or _file_paths(data):
        return compress_files(structure, data, client=client, reader=reader, chunk=chunk, progress=progress).equations
    return compress_trajectories(structure, data, chunk=chunk, progress=progress, overlap=overlap)

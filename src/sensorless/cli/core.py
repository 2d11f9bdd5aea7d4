"""Core commands, by concept: :mod:`.identify` (the run: :mod:`sensorless.run`), :mod:`.predict`
(predict, demo) and :mod:`.bench` (benchmarks)."""

from __future__ import annotations

from .identify import identify  # (import order = order in --help)
from .predict import demo, predict
from . import bench  # noqa: F401  (registers the benchmark commands)

__all__ = ["identify", "predict", "demo"]

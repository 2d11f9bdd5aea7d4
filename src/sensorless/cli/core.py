"""Core commands, by concept: :mod:`.identify` (with :mod:`.identify_model` and
:mod:`.identify_outputs`) and :mod:`.predict`.

This module keeps the names other modules and tests import from ``sensorless.cli.core``."""

from __future__ import annotations

from .identify import identify  # (import order = order in --help)
from .predict import predict
from .identify_model import _check_identify_options, _friction_options, _lmi_kwargs, _plain, _structure
from .identify_outputs import PLOT_POINTS, PLOT_WINDOW, _plot_window, _print_bodies

__all__ = ["identify", "predict", "PLOT_WINDOW", "PLOT_POINTS", "_plot_window", "_friction_options",
           "_lmi_kwargs", "_structure", "_check_identify_options", "_plain", "_print_bodies"]

"""Values no run can use, refused before any work (OptionError naming the field, ``solver.gamma``)."""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import OptionError, setting
from .config import RunConfig

__all__ = ["check_run_config", "auto_or_number"]


def auto_or_number(field: str, text, *, positive: bool = False):
    """``"auto"``, or ``text`` as a finite number ≥ 0 (> 0 with ``positive``); OptionError naming ``field``."""
    if str(text).strip().lower() == "auto":
        return "auto"
    try:
        x = float(text)
    except ValueError:
        raise OptionError(f"{setting(field)} must be a number or 'auto', got '{text}'") from None
    if not (math.isfinite(x) and x >= 0) or (positive and x == 0):
        raise OptionError(f"{setting(field)} must be a finite number {'>' if positive else '>='} 0 or 'auto', "
                          f"got '{text}'")
    return x


def _choice(field: str, value, choices) -> None:
    if value not in choices:
        raise OptionError(f"{setting(field)} must be one of {', '.join(choices)}, got '{value}'")


def check_run_config(config: RunConfig) -> tuple:
    """Check ``config`` (module docstring); returns the friction law's (coulomb_smoothing, stribeck_velocity),
    each ``"auto"`` or a number."""
    from ..data.outliers import OUTLIER_MODES
    from ..data.prepare import check_preprocessing
    from ..identification import METHODS
    from ..identification.urdf_values import URDF_VALUES

    logs, model, solver, ex = config.logs, config.model, config.solver, config.execution
    if not model.robot:
        raise OptionError(f"{setting('model.robot')}: no robot given")
    if not logs.data:
        raise OptionError(f"{setting('logs.data')}: no training log given")
    _choice("solver.urdf_values", solver.urdf_values, URDF_VALUES)
    eps = auto_or_number("model.coulomb_smoothing", model.coulomb_smoothing)
    vs = auto_or_number("model.stribeck_velocity", model.stribeck_velocity, positive=True)
    _choice("solver.method", solver.method, METHODS)
    if solver.gamma != "auto":
        try:
            g = float(solver.gamma)
        except ValueError:
            raise OptionError(f"{setting('solver.gamma')} must be a number or 'auto', got '{solver.gamma}'") from None
        if not (math.isfinite(g) and g >= 0):
            raise OptionError(f"{setting('solver.gamma')} must be a finite number >= 0 or 'auto', got '{solver.gamma}'")
    if solver.regularization not in ("none", "pullback"):  # the default is checked without loading cvxpy
        from ..identification.regularizers import REGULARIZERS

        _choice("solver.regularization", solver.regularization, (*sorted(REGULARIZERS), "none"))
    _choice("logs.outliers", logs.outliers, OUTLIER_MODES)
    if solver.weights not in ("auto", "none") and not Path(solver.weights).is_file():
        raise OptionError(f"{setting('solver.weights')} must be auto, none or a JSON/CSV file of per-joint σ; no file "
                          f"'{solver.weights}'")
    check_preprocessing(logs.rate, logs.lowpass, logs.savgol_window, logs.decimate)
    if ex.workers is not None and ex.scheduler is None:
        raise OptionError(f"{setting('execution.workers')} needs {setting('execution.scheduler')} "
                          "(local or tcp://HOST:PORT)")
    if ex.scheduler is not None and "presliding" in model.joint_terms:
        raise OptionError(f"{setting('model.joint_terms')} presliding needs the whole logs in order (its state "
                          f"depends on the history of q): run without {setting('execution.scheduler')}")
    if logs.wrench_frame and model.contact_mode != "wrench":
        raise OptionError(f"{setting('logs.wrench_frame')} needs {setting('model.contact_mode', 'wrench')} "
                          "(measured contact wrenches)")
    return eps, vs

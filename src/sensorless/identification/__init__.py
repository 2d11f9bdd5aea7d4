"""Identification: base parameters, solvers, metrics and results."""

from .base import BaseParameters, base_parameters
from .identify import METHODS, identify
from .least_squares import LeastSquaresSolution, excitation_check, solve_least_squares
from .metrics import TorqueMetrics, torque_metrics
from .result import IdentificationResult

__all__ = [
    "BaseParameters",
    "IdentificationResult",
    "LeastSquaresSolution",
    "METHODS",
    "TorqueMetrics",
    "base_parameters",
    "excitation_check",
    "identify",
    "solve_least_squares",
    "torque_metrics",
]

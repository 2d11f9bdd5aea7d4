"""Identification: base parameters, solvers, metrics and results."""

from .base import BaseParameters, base_parameters
from .identifiability import identifiability_report
from .identify import METHODS, identify
from .least_squares import LeastSquaresSolution, excitation_check, solve_least_squares, solve_truncated_svd
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
    "identifiability_report",
    "identify",
    "solve_least_squares",
    "solve_truncated_svd",
    "torque_metrics",
]

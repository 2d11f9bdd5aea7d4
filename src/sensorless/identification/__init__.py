"""Identification: base parameters, solvers, metrics and results."""

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

from .base import base_parameters
from .identifiability import identifiability_report
from .identify import CONSTRAINT_RESIDUAL_RISE, METHODS, identify
from .ellipsoids import auto_ellipsoids
from .metrics import torque_metrics
from .weights import check_weights, read_weights_file

# cvxpy (~0.4 s to import) is loaded with the LMI modules, on first use (PEP 562); so are the
# payload and fleet modules (`sensorless identify` on an arm needs none of them)
__getattr__, __dir__ = lazy_exports(globals(), {
    "identify_files": ".fleet",
    "identify_payload": ".payload",
    "solve_lmi": ".lmi",
    "cross_validate_gamma": ".gamma",
})

if TYPE_CHECKING:
    from .fleet import identify_files
    from .payload import identify_payload
    from .gamma import cross_validate_gamma
    from .lmi import solve_lmi


__all__ = [
    "CONSTRAINT_RESIDUAL_RISE",
    "check_weights",
    "read_weights_file",
    "auto_ellipsoids",
    "cross_validate_gamma",
    "solve_lmi",
    "METHODS",
    "base_parameters",
    "identifiability_report",
    "identify",
    "identify_files",
    "identify_payload",
    "torque_metrics",
]

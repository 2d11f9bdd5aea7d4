"""Actuator models of position-controlled joints and their identification."""

from .fits import (
    AsymmetricSolution,
    asymmetric_least_squares,
    fit_asymmetric,
    fit_current_model,
    fit_least_squares,
    fit_piecewise_linear,
    fit_two_stage,
    unsaturated,
)
from .model import (
    CurrentModel,
    MotorModel,
    PiecewiseLinearModel,
    over_estimation,
    over_estimation_fraction,
)

__all__ = [
    "AsymmetricSolution",
    "CurrentModel",
    "MotorModel",
    "PiecewiseLinearModel",
    "asymmetric_least_squares",
    "fit_asymmetric",
    "fit_current_model",
    "fit_least_squares",
    "fit_piecewise_linear",
    "fit_two_stage",
    "unsaturated",
    "over_estimation",
    "over_estimation_fraction",
]

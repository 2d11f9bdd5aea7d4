"""Actuator models of position-controlled joints (:mod:`.model`) and their identification (:mod:`.fits`)."""

from .fits import (
    asymmetric_least_squares,
    fit_asymmetric,
    fit_current_model,
    fit_least_squares,
    fit_piecewise_linear,
    fit_two_stage,
    unsaturated,
)
from .model import MotorModel, over_estimation_fraction

__all__ = [
    "MotorModel",
    "asymmetric_least_squares",
    "fit_asymmetric",
    "fit_current_model",
    "fit_least_squares",
    "fit_piecewise_linear",
    "fit_two_stage",
    "over_estimation_fraction",
    "unsaturated",
]

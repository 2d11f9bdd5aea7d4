"""Actuator models of position-controlled joints (:mod:`.model`) and their identification (:mod:`.fits`)."""

from . import fits
from .fits import *  # noqa: F403  the fits and their solution (fits.__all__)
from .model import MotorModel, over_estimation_fraction

__all__ = sorted(["MotorModel", "over_estimation_fraction", *fits.__all__])

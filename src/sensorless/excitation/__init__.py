"""Excitation trajectories: finite Fourier series (:mod:`.fourier`), their limits and random
baseline (:mod:`.limits`), conditioning criteria (:mod:`.criteria`) and the optimised design
(:mod:`.design`, solving the problem of :mod:`.problem`)."""

from .criteria import excitation_metrics
from .design import ExcitationDesign, design_excitation
from .fourier import FourierTrajectory, random_fourier
from .limits import (
    CartesianBox,
    ExcitationLimits,
    check_export,
    check_sampled_limits,
    random_excitation,
    robot_limits,
)

__all__ = [
    "CartesianBox",
    "ExcitationDesign",
    "ExcitationLimits",
    "FourierTrajectory",
    "check_export",
    "check_sampled_limits",
    "design_excitation",
    "excitation_metrics",
    "random_excitation",
    "random_fourier",
    "robot_limits",
]

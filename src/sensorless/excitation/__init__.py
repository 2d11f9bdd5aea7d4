"""Excitation trajectories: finite Fourier series (:mod:`.fourier`), their limits and random
baseline (:mod:`.limits`), conditioning criteria (:mod:`.criteria`) and the optimised design
(:mod:`.design`, solving the problem of :mod:`.problem`)."""

from . import limits
from .criteria import excitation_metrics
from .design import ExcitationDesign, design_excitation
from .fourier import FourierTrajectory, random_fourier
from .limits import *  # noqa: F403  the limits, their checks and the random baseline (limits.__all__)

__all__ = sorted(["ExcitationDesign", "FourierTrajectory", "design_excitation", "excitation_metrics", "random_fourier",
                  *limits.__all__])

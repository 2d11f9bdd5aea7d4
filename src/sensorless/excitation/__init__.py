"""Excitation trajectories: finite Fourier series (:mod:`.fourier`), their limits and random
baseline (:mod:`.limits`), conditioning criteria (:mod:`.criteria`) and the optimised design
(:mod:`.design`, solving the problem of :mod:`.problem`)."""

from . import criteria, design, fourier, limits
from .criteria import *  # noqa: F403
from .design import *  # noqa: F403
from .fourier import *  # noqa: F403
from .limits import *  # noqa: F403

__all__ = sorted([*criteria.__all__, *design.__all__, *fourier.__all__, *limits.__all__])

"""Robot models authored in code (robots without a usable URDF)."""

from . import dvrk_psm
from .dvrk_psm import *  # noqa: F403  (the names in dvrk_psm.__all__)

__all__ = list(dvrk_psm.__all__)

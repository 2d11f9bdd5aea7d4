"""Actuator models of position-controlled joints (:mod:`.model`) and their identification (:mod:`.fits`)."""

from . import fits, model
from .fits import *  # noqa: F403
from .model import *  # noqa: F403

__all__ = [*fits.__all__, *model.__all__]

"""Regressor terms and streaming compression."""

from .compress import NormalEquations, compress, iter_trajectories
from .terms import JOINT_TERMS, ModelStructure

__all__ = ["JOINT_TERMS", "ModelStructure", "NormalEquations", "compress", "iter_trajectories"]

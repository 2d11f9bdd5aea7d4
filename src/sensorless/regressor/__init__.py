"""Regressor terms and streaming compression."""

from .compress import NormalEquations, compress, iter_trajectories
from .distributed import DistributedError, FleetEquations, LogReader, compress_files, expand_paths
from .contact import ContactStructure, contact_jacobians, detect_contacts, null_space_projector
from .terms import JOINT_TERMS, ModelStructure

__all__ = [
    "ContactStructure",
    "contact_jacobians",
    "detect_contacts",
    "null_space_projector",
    "JOINT_TERMS",
    "ModelStructure", "NormalEquations", "compress", "iter_trajectories",
    "DistributedError", "FleetEquations", "LogReader", "compress_files", "expand_paths"]

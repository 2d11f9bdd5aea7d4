"""Regressor terms and streaming compression."""

from .compress import compress
from .normal_equations import NormalEquations
from .contact import ContactStructure
from .contact_kinematics import detect_contacts, null_space_projector
from .distributed import LogReader, compress_files, expand_paths
from .terms import ModelStructure
from .joint_terms import JOINT_TERMS

__all__ = [
    "ContactStructure",
    "detect_contacts",
    "null_space_projector",
    "JOINT_TERMS",
    "ModelStructure", "NormalEquations", "compress",
    "LogReader", "compress_files", "expand_paths"]

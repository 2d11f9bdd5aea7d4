"""Regressor terms and streaming compression."""

from .compress import compress
from .normal_equations import NormalEquations, iter_trajectories
from .contact import WRENCH_OFFSETS, ContactStructure, choose_contact_rows
from .contact_kinematics import (
    contact_jacobians,
    contact_rotations,
    detect_contacts,
    null_space_basis,
    null_space_projector,
)
from .distributed import FleetEquations, LogReader, compress_files, expand_paths
from ..errors import DistributedError
from .rowmap import ActuatedRows, ContactNullSpace, RowMap, TransmissionRows
from .terms import ModelStructure
from .joint_spec import JOINT_TERMS

__all__ = [
    "ActuatedRows", "ContactNullSpace", "RowMap", "TransmissionRows",
    "ContactStructure",
    "WRENCH_OFFSETS",
    "choose_contact_rows",
    "contact_jacobians",
    "contact_rotations",
    "detect_contacts",
    "null_space_basis",
    "null_space_projector",
    "JOINT_TERMS",
    "ModelStructure", "NormalEquations", "compress", "iter_trajectories",
    "DistributedError", "FleetEquations", "LogReader", "compress_files", "expand_paths"]

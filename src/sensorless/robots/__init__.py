"""Robot models authored in code (robots without a usable URDF)."""

from .dvrk_psm import (
    COORDINATES,
    LENGTHS,
    MOTOR_TO_JOINT,
    PSM_BODIES_AUTHORS,
    PSM_FRAMES,
    PSM_LIMITS,
    PSM_NAMES,
    mdh_placement,
    psm_drives,
    psm_robot,
    psm_structure,
    psm_tree,
    published_parameters,
    read_psm_log,
)

__all__ = [
    "COORDINATES",
    "LENGTHS",
    "MOTOR_TO_JOINT",
    "PSM_BODIES_AUTHORS",
    "PSM_FRAMES",
    "PSM_LIMITS",
    "PSM_NAMES",
    "mdh_placement",
    "psm_drives",
    "psm_robot",
    "psm_structure",
    "psm_tree",
    "published_parameters",
    "read_psm_log",
]

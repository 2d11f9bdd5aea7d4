"""Robot models authored in code (robots without a usable URDF)."""

from typing import TYPE_CHECKING

from .._lazy import lazy_exports
from .names import PSM_NAMES

# the PSM model (Pinocchio, regressor) is imported on first use: the CLI only needs PSM_NAMES to start
__getattr__, __dir__ = lazy_exports(globals(), dict.fromkeys(
    ["COORDINATES", "LENGTHS", "MOTOR_TO_JOINT", "PSM_BODIES_AUTHORS", "PSM_FRAMES", "PSM_LIMITS", "mdh_placement",
     "psm_drives", "psm_robot", "psm_structure", "psm_tree", "published_parameters", "read_psm_log"], ".dvrk_psm"))

if TYPE_CHECKING:
    from .dvrk_psm import (
        COORDINATES,
        LENGTHS,
        MOTOR_TO_JOINT,
        PSM_BODIES_AUTHORS,
        PSM_FRAMES,
        PSM_LIMITS,
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

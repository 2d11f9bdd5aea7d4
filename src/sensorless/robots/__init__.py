"""Robot models authored in code (robots without a usable URDF)."""

from ..lazy import lazy_exports
from .names import PSM_NAMES

# the PSM model (Pinocchio, regressor) is imported on first use: the CLI only needs PSM_NAMES to start
_PSM_MODEL = ["COORDINATES", "LENGTHS", "MOTOR_TO_JOINT", "PSM_BODIES_AUTHORS", "PSM_FRAMES", "PSM_LIMITS",
              "mdh_placement", "psm_drives", "psm_robot", "psm_structure", "psm_tree", "published_parameters",
              "read_psm_log"]
__getattr__, __dir__ = lazy_exports(globals(), dict.fromkeys(_PSM_MODEL, ".dvrk_psm"))


__all__ = ["PSM_NAMES", *_PSM_MODEL]

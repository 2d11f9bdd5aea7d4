"""Named robots: the registry :func:`sensorless.robot.load_robot` consults (:mod:`.registry`, one entry per
robot or catalogue; :mod:`.base`), and the robots authored in code, one module each (the dVRK PSM,
:mod:`.dvrk_psm`). ``sensorless.robot`` is the :class:`~sensorless.robot.Robot` class and its loader."""

from ..lazy import lazy_exports

# the PSM model (Pinocchio, regressor) is imported on first use
_PSM_MODEL = ["COORDINATES", "LENGTHS", "MOTOR_TO_JOINT", "PSM_BODIES_AUTHORS", "PSM_FRAMES", "PSM_LIMITS",
              "mdh_placement", "psm_drives", "psm_robot", "psm_structure", "psm_tree", "published_parameters",
              "read_psm_log"]
__getattr__, __dir__ = lazy_exports(globals(), dict.fromkeys(_PSM_MODEL, ".dvrk_psm"))


__all__ = [*_PSM_MODEL]

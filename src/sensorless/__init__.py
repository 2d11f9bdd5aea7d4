"""sensorless: physically consistent dynamic models, torque and force estimation
for robots without joint-torque or force sensors.

The spine: τ = W(q, v, v̇) π, identified from logs (`identify`), predicted on new
logs (`IdentificationResult.predict`), exported as URDF (`write_urdf`).
"""

from typing import TYPE_CHECKING

from .lazy import lazy_exports
from .errors import SensorlessError

# Public names are imported on first use (PEP 562): `import sensorless` and the CLI's start-up
# do not pay for Pinocchio, SciPy, cvxpy, matplotlib or torch until a command needs them.
_EXPORTS = {
    **dict.fromkeys(["Trajectory", "read_trajectory", "validate_trajectory"], ".data"),
    **dict.fromkeys(["CADModel", "PhysicalModel", "TorqueModel"], ".estimators"),
    **dict.fromkeys(["FourierTrajectory", "random_fourier"], ".excitation"),
    "write_urdf": ".export",
    **dict.fromkeys(["IdentificationResult", "base_parameters", "identify", "torque_metrics"], ".identification"),
    **dict.fromkeys(["check_physical_consistency", "is_physically_consistent"], ".parameters"),
    **dict.fromkeys(["ModelStructure", "NormalEquations", "compress"], ".regressor"),
    **dict.fromkeys(["Robot", "load_robot"], ".robot"),
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:  # static analysers see the eager imports
    from .data import Trajectory, read_trajectory, validate_trajectory
    from .estimators import CADModel, PhysicalModel, TorqueModel
    from .excitation import FourierTrajectory, random_fourier
    from .export import write_urdf
    from .identification import IdentificationResult, base_parameters, identify, torque_metrics
    from .parameters import check_physical_consistency, is_physically_consistent
    from .regressor import ModelStructure, NormalEquations, compress
    from .robot import Robot, load_robot

__version__ = "0.1.0"

__all__ = [
    "CADModel",
    "FourierTrajectory",
    "IdentificationResult",
    "ModelStructure",
    "NormalEquations",
    "PhysicalModel",
    "Robot",
    "SensorlessError",
    "TorqueModel",
    "Trajectory",
    "base_parameters",
    "check_physical_consistency",
    "compress",
    "identify",
    "is_physically_consistent",
    "load_robot",
    "random_fourier",
    "read_trajectory",
    "torque_metrics",
    "validate_trajectory",
    "write_urdf",
]

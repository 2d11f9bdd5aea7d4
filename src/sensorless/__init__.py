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
    "Trajectory": ".data.trajectory", "read_trajectory": ".data.readers", "validate_trajectory": ".data.validation",
    **dict.fromkeys(["CADModel", "PhysicalModel", "TorqueModel"], ".torque_models"),
    **dict.fromkeys(["FourierTrajectory", "random_fourier"], ".excitation.fourier"),
    "write_urdf": ".export",
    "IdentificationResult": ".identification.result", "base_parameters": ".identification.base",
    "identify": ".identification.identify", "torque_metrics": ".identification.metrics",
    **dict.fromkeys(["check_physical_consistency", "is_physically_consistent"], ".parameters"),
    "ModelStructure": ".regressor.terms", "NormalEquations": ".regressor.normal_equations", "compress": ".regressor.compress",
    **dict.fromkeys(["Robot", "load_robot"], ".robot"),
    **dict.fromkeys(["RunConfig", "identify_run"], ".run"),
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:  # static analysers see the eager imports
    from .data.readers import read_trajectory
    from .data.trajectory import Trajectory
    from .data.validation import validate_trajectory
    from .excitation.fourier import FourierTrajectory, random_fourier
    from .export import write_urdf
    from .identification.base import base_parameters
    from .identification.identify import identify
    from .identification.metrics import torque_metrics
    from .identification.result import IdentificationResult
    from .parameters import check_physical_consistency, is_physically_consistent
    from .regressor.compress import compress
    from .regressor.normal_equations import NormalEquations
    from .regressor.terms import ModelStructure
    from .robot import Robot, load_robot
    from .run import RunConfig, identify_run
    from .torque_models import CADModel, PhysicalModel, TorqueModel

__version__ = "0.1.0"

__all__ = [
    "CADModel",
    "FourierTrajectory",
    "IdentificationResult",
    "ModelStructure",
    "NormalEquations",
    "PhysicalModel",
    "Robot",
    "RunConfig",
    "SensorlessError",
    "TorqueModel",
    "Trajectory",
    "base_parameters",
    "check_physical_consistency",
    "compress",
    "identify",
    "identify_run",
    "is_physically_consistent",
    "load_robot",
    "random_fourier",
    "read_trajectory",
    "torque_metrics",
    "validate_trajectory",
    "write_urdf",
]

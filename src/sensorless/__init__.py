"""sensorless: physically consistent dynamic models, torque and force estimation
for robots without joint-torque or force sensors.

The spine: τ = W(q, v, v̇) π, identified from logs (`identify`), predicted on new
logs (`IdentificationResult.predict`), exported as URDF (`write_urdf`).
"""

from .data import Trajectory, read_trajectory, validate_trajectory
from .errors import SensorlessError
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

"""Identification: base parameters, solvers, metrics and results."""

from .base import BaseParameters, base_parameters
from .identifiability import identifiability_report
from .identify import METHODS, identify
from .constraints import (
    BodyMassBounds,
    ComInEllipsoid,
    DensityRealizable,
    NonNegativeArmature,
    NonNegativeFriction,
    PseudoInertiaPSD,
    TotalMass,
    default_constraints,
)
from .ellipsoids import BoundingEllipsoid, auto_ellipsoids
from .fleet import identify_files, identify_fleet
from .least_squares import LeastSquaresSolution, excitation_check, solve_least_squares, solve_truncated_svd
from .lmi import GammaSelection, LmiSolution, build_lmi, cross_validate_gamma, select_gamma, solve_lmi
from .metrics import TorqueMetrics, torque_metrics
from .payload import JointConsistency, PayloadEstimate, identify_payload, payload_regressor, point_mass_parameters
from .result import IdentificationResult
from .floating_base import base_wrench_metrics, com_cop_check, com_positions, standing_mask

from .drive_gains import DriveGains, clock_offset, identify_drive_gains, payload_torque
from .friction import (
    FrictionFit,
    coulomb_smoothing_from_noise,
    friction_curve,
    friction_residual,
    identify_friction,
    search_stribeck_velocity,
    signal_noise,
)
from .uncertainty import JointMotion, base_parameter_uncertainty, check_joint_motion, poorly_identified

__all__ = ["clock_offset", 
    "DriveGains",
    "FrictionFit",
    "coulomb_smoothing_from_noise",
    "friction_curve",
    "friction_residual",
    "identify_drive_gains",
    "identify_friction",
    "payload_torque",
    "search_stribeck_velocity",
    "signal_noise",
    "base_wrench_metrics",
    "com_cop_check",
    "com_positions",
    "standing_mask",
    "JointMotion",
    "base_parameter_uncertainty",
    "check_joint_motion",
    "poorly_identified",
    "BodyMassBounds",
    "BoundingEllipsoid",
    "ComInEllipsoid",
    "DensityRealizable",
    "GammaSelection",
    "LmiSolution",
    "NonNegativeArmature",
    "NonNegativeFriction",
    "PseudoInertiaPSD",
    "TotalMass",
    "auto_ellipsoids",
    "build_lmi",
    "cross_validate_gamma",
    "default_constraints",
    "select_gamma",
    "solve_lmi",
    "BaseParameters",
    "IdentificationResult",
    "JointConsistency",
    "PayloadEstimate",
    "LeastSquaresSolution",
    "METHODS",
    "TorqueMetrics",
    "base_parameters",
    "excitation_check",
    "identifiability_report",
    "identify",
    "identify_files",
    "identify_fleet",
    "identify_payload",
    "payload_regressor",
    "point_mass_parameters",
    "solve_least_squares",
    "solve_truncated_svd",
    "torque_metrics",
]

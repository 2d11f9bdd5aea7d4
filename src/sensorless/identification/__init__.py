"""Identification: base parameters, solvers, metrics and results."""

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

from .base import BaseParameters, base_parameters
from .identifiability import identifiability_report
from .identify import CONSTRAINT_RESIDUAL_RISE, JOINT_TERM_MAX_VIF, METHODS, identify
from .ellipsoids import PRIOR_COM_MARGIN, PRIOR_SLACK, BoundingEllipsoid, auto_ellipsoids
from .least_squares import (
    LeastSquaresSolution,
    excitation_check,
    joint_term_inflation,
    row_weights,
    solve_least_squares,
    solve_truncated_svd,
    two_step_sigma,
)
from .metrics import TorqueMetrics, torque_metrics
from .result import IdentificationResult

from .friction import (
    FrictionFit,
    coulomb_smoothing_from_noise,
    friction_curve,
    friction_residual,
    search_stribeck_velocity,
    stribeck_grid,
)
from ..data.rest import signal_noise
from .friction_search import identify_friction
from .stribeck import StribeckCandidates, choose_stribeck
from .weights import check_weights, read_weights_file, weights_option
from .uncertainty import JointMotion, base_parameter_uncertainty, check_joint_motion, poorly_identified

# cvxpy (~0.4 s to import) is loaded with the LMI modules, on first use (PEP 562); so are the
# payload, drive-gain, fleet and floating-base modules (`sensorless identify` on an arm needs none of them)
__getattr__, __dir__ = lazy_exports(globals(), {
    **dict.fromkeys(["identify_files", "identify_fleet"], ".fleet"),
    "identify_payload": ".payload",
    **dict.fromkeys(["JointConsistency", "PayloadEstimate", "payload_regressor", "point_mass_parameters"], ".payload_model"),
    **dict.fromkeys(["base_wrench_metrics", "com_cop_check", "com_positions", "standing_mask"], ".floating_base"),
    **dict.fromkeys(["DriveGains", "identify_drive_gains", "payload_torque"], ".drive_gains"),
    **dict.fromkeys(["BodyMassBounds", "ComInEllipsoid", "DensityRealizable", "NonNegativeArmature",
                     "NonNegativeFriction", "PseudoInertiaPSD", "TotalMass", "default_constraints"], ".constraints"),
    **dict.fromkeys(["LmiSolution", "build_lmi", "solve_lmi"], ".lmi"),
    **dict.fromkeys(["GammaSelection", "cross_validate_gamma", "select_gamma"], ".gamma"),
})

if TYPE_CHECKING:
    from .drive_gains import DriveGains, identify_drive_gains, payload_torque
    from .fleet import identify_files, identify_fleet
    from .floating_base import base_wrench_metrics, com_cop_check, com_positions, standing_mask
    from .payload import identify_payload
    from .payload_model import JointConsistency, PayloadEstimate, payload_regressor, point_mass_parameters
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
    from .gamma import GammaSelection, cross_validate_gamma, select_gamma
    from .lmi import LmiSolution, build_lmi, solve_lmi


__all__ = [
    "DriveGains",
    "FrictionFit",
    "coulomb_smoothing_from_noise",
    "friction_curve",
    "friction_residual",
    "identify_drive_gains",
    "identify_friction",
    "payload_torque",
    "search_stribeck_velocity",
    "stribeck_grid",
    "StribeckCandidates",
    "choose_stribeck",
    "signal_noise",
    "CONSTRAINT_RESIDUAL_RISE",
    "JOINT_TERM_MAX_VIF",
    "PRIOR_COM_MARGIN",
    "PRIOR_SLACK",
    "check_weights",
    "joint_term_inflation",
    "read_weights_file",
    "row_weights",
    "two_step_sigma",
    "weights_option",
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

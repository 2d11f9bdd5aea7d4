"""IdentificationResult: parameters, base-parameter report, diagnostics and settings."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.trajectory import Trajectory
from ..io import versions, write_json_atomic  # re-exported: the writers live in sensorless.io
from ..regressor.terms import ModelStructure
from .base import BaseParameters
from .metrics import TorqueMetrics, torque_metrics

__all__ = ["IdentificationResult", "versions", "write_json_atomic"]


@dataclass
class IdentificationResult:
    """Outcome of :func:`~sensorless.identification.identify`.

    ``parameters`` are standard parameters (layout of ``structure.labels``) that
    reproduce the identified base parameters exactly; ``parameters_kind`` says how the
    unidentifiable directions were fixed ("closest_to_prior" or "min_norm").
    """

    method: str
    structure: ModelStructure
    base: BaseParameters
    base_values: np.ndarray
    parameters: np.ndarray
    parameters_kind: str
    train_metrics: TorqueMetrics
    diagnostics: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    @property
    def robot(self):
        return self.structure.robot

    @property
    def labels(self) -> list[str]:
        return self.structure.labels

    @property
    def inertial_parameters(self) -> np.ndarray:
        return self.parameters[: self.structure.n_body_params]

    def joint_terms(self) -> dict[str, dict[str, float]]:
        s = self.structure
        return {
            j: {t: float(self.parameters[s.joint_term_index(j, t)]) for t in s.joint_terms}
            for j in s.robot.actuated_joints
        }

    def predict(self, traj: Trajectory) -> np.ndarray:
        """Predicted effort (N, n_rows) for a trajectory with q, v, a."""
        return self.structure.torques(self.parameters, traj)

    def evaluate(self, traj: Trajectory) -> TorqueMetrics:
        """Per-joint metrics of the prediction on a (held-out) trajectory."""
        return torque_metrics(self.structure.target(traj), self.predict(traj), self.structure.row_names)

    def to_dict(self) -> dict:
        return {
            "method": self.method,
            "robot": self.robot.summary(),
            "parameters": dict(zip(self.labels, map(float, self.parameters))),
            "parameters_kind": self.parameters_kind,
            "joint_terms": self.joint_terms(),
            "base_parameters": {
                **self.base.to_dict(),
                "values": self.base_values.tolist(),
            },
            "train_metrics": self.train_metrics.to_dict(),
            "diagnostics": self.diagnostics,
            "settings": self.settings,
            "versions": versions(),
        }

    def save_json(self, path: str | Path) -> None:
        write_json_atomic(self.to_dict(), path)

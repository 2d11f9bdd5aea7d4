"""IdentificationResult: parameters, base-parameter report, diagnostics and settings."""

from __future__ import annotations

import json
import os
import platform
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.trajectory import Trajectory
from ..regressor.terms import ModelStructure
from .base import BaseParameters
from .metrics import TorqueMetrics, torque_metrics

__all__ = ["IdentificationResult", "versions", "write_json_atomic"]


def versions() -> dict:
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("sensorless", "pin", "numpy", "scipy", "cvxpy", "clarabel"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def write_json_atomic(obj: dict, path: str | Path) -> None:
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(obj, f, indent=2, default=_jsonable)
    os.chmod(tmp, 0o644)  # mkstemp creates 0600
    os.replace(tmp, path)


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x)}")


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

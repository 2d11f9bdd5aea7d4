"""IdentificationResult: parameters, base-parameter report, diagnostics and settings."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..data.trajectory import Trajectory
from ..io import versions
from ..regressor.terms import ModelStructure
from .base import BaseParameters
from .metrics import TorqueMetrics, torque_metrics

if TYPE_CHECKING:
    from ..regressor.normal_equations import NormalEquations

__all__ = ["IdentificationResult", "body_links", "parameter_links"]


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
    #: the compressed normal equations the parameters were solved on (not written to result.json):
    #: another solver on the same data (e.g. the CLI's OLS baseline) is a solve, not a second pass
    equations: "NormalEquations | None" = field(default=None, repr=False, compare=False)

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
            j: {t: float(self.parameters[s.joint_term_index(j, t)]) for t in s.terms_of(j)}
            for j in s.robot.term_joints
        }

    def predict(self, traj: Trajectory) -> np.ndarray:
        """Predicted effort (N, n_rows) for a trajectory with q, v, a."""
        return self.structure.torques(self.parameters, traj)

    def score(self, traj: Trajectory) -> TorqueMetrics:
        """Per-joint metrics of the prediction on a (held-out) trajectory (:func:`~.metrics.torque_metrics`,
        as every model's ``score``)."""
        return torque_metrics(self.structure.target(traj), self.predict(traj), self.structure.row_names)

    def mass_properties(self) -> dict | None:
        """Identified total mass Σ m_k [kg] and CoM [m] (base frame, neutral configuration) of a
        floating-base robot, next to the model file's (``urdf_*``); None for a fixed base, whose
        total mass is not identifiable. Both are functions of base parameters here (the gravity
        wrench on the base is M g at the CoM), so they do not depend on ``parameters_kind``."""
        if not getattr(self.robot, "floating_base", False):
            return None
        import pinocchio as pin

        model, data = self.robot.model, self.robot.data
        pin.forwardKinematics(model, data, pin.neutral(model))
        place = [data.oMi[k + 1] for k in range(self.robot.n_bodies)]

        def mass_com(pi: np.ndarray) -> tuple[float, list[float]]:
            """M = Σ m_k, c = Σ (m_k p_k + R_k h_k) / M with h_k = m_k c_k (no Inertia objects:
            the parameters need not be physical)."""
            pi = np.asarray(pi, float).reshape(-1, 10)
            M = float(pi[:, 0].sum())
            first = sum(pi[k, 0] * P.translation + P.rotation @ pi[k, 1:4] for k, P in enumerate(place))
            return M, [float(x) for x in np.asarray(first) / M] if M != 0 else [float("nan")] * 3

        m, c = mass_com(self.inertial_parameters)
        m0, c0 = mass_com(self.robot.inertial_parameters())
        return {"total_mass": m, "com": c, "urdf_total_mass": m0, "urdf_com": c0,
                "com_frame": "base frame at the neutral configuration"}

    def to_dict(self) -> dict:
        from .artifact import SCHEMA_VERSION, robot_settings

        mass = self.mass_properties()
        return {
            "schema_version": SCHEMA_VERSION,
            "method": self.method,
            "robot": self.robot.summary(),
            **({"mass_properties": mass} if mass is not None else {}),
            "parameters": dict(zip(self.labels, map(float, self.parameters))),
            "parameter_links": parameter_links(self.robot, self.labels),
            "parameters_kind": self.parameters_kind,
            "joint_terms": self.joint_terms(),
            "base_parameters": {
                **self.base.to_dict(),
                "values": self.base_values.tolist(),
            },
            "train_metrics": self.train_metrics.to_dict(),
            "diagnostics": self.diagnostics,
            "settings": {**self.settings, "robot": robot_settings(self.robot)},
            "versions": versions(),
        }

    def save_json(self, path: str | Path) -> None:
        """Only ``result.json``; :func:`~.artifact.save_model_folder` writes the whole model folder."""
        from .artifact import write_result

        write_result(self.to_dict(), path)


def body_links(robot) -> dict[str, str]:
    """{body (joint) name: link name}: the first BODY frame on each joint (URDF link), e.g.
    ``shoulder_pan_joint`` -> ``shoulder_link``; a joint without one keeps its own name."""
    import pinocchio as pin

    m = robot.model
    out = {}
    for b in robot.body_names:
        jid = m.getJointId(b) if m.existJointName(b) else None
        link = next((f.name for f in m.frames if jid is not None and f.parentJoint == jid
                     and f.type == pin.FrameType.BODY), None)
        out[b] = link or b
    return out


def parameter_links(robot, labels) -> dict[str, str]:
    """Each inertial parameter label ``joint.p`` with its link name, ``link.p`` (``shoulder_link.m``)."""
    links = body_links(robot)
    out = {}
    for lab in labels:
        body, _, p = lab.rpartition(".")
        if body in links:
            out[lab] = f"{links[body]}.{p}"
    return out

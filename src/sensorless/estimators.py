"""Torque models with one scikit-learn-style interface, so comparisons are one loop.

    model.fit(trajectories) -> model
    model.predict(trajectory) -> τ̂ (N, n_rows)

Hyper-parameters go in ``__init__``; learned state in attributes ending in ``_``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Iterable, Protocol, Sequence

import numpy as np

from .data.trajectory import Trajectory
from .errors import SensorlessError
from .identification.identify import identify
from .identification.metrics import TorqueMetrics, torque_metrics
from .identification.result import IdentificationResult
from .regressor.terms import ModelStructure
from .robot import Robot

__all__ = ["TorqueModel", "PhysicalModel", "CADModel", "load_parameters"]


class TorqueModel(Protocol):
    def fit(self, data: Trajectory | Iterable[Trajectory]) -> "TorqueModel": ...

    def predict(self, traj: Trajectory) -> np.ndarray: ...


class _Scored:
    structure_: ModelStructure

    def score(self, traj: Trajectory) -> TorqueMetrics:
        """Per-joint metrics of the prediction against the measured effort."""
        return torque_metrics(self.structure_.target(traj), self.predict(traj), self.structure_.row_names)

    def predict(self, traj: Trajectory) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError


class PhysicalModel(_Scored):
    """Identified rigid-body model + joint terms (see :func:`sensorless.identification.identify`)."""

    def __init__(
        self,
        robot: Robot,
        method: str = "ols",
        joint_terms: Sequence[str] = ("fv", "fc", "offset", "armature"),
        **identify_kwargs,
    ) -> None:
        self.robot = robot
        self.method = method
        self.joint_terms = tuple(joint_terms)
        self.identify_kwargs = identify_kwargs

    def get_params(self) -> dict:
        return {"method": self.method, "joint_terms": list(self.joint_terms), **self.identify_kwargs}

    def fit(self, data) -> "PhysicalModel":
        make = getattr(self.robot, "make_structure", None)  # a transmission's coordinate robot (e.g. the PSM)
        self.structure_ = make(self.joint_terms) if make else ModelStructure(self.robot, joint_terms=self.joint_terms)
        self.result_: IdentificationResult = identify(self.structure_, data, method=self.method, **self.identify_kwargs)
        self.parameters_ = self.result_.parameters
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        return self.structure_.torques(self.parameters_, traj)


class CADModel(_Scored):
    """The robot model file as it is (its inertials and armature, no friction): the baseline."""

    def __init__(self, robot: Robot, like: ModelStructure | None = None) -> None:
        """``like``: score on the same equations as this structure (e.g. a contact projection)."""
        self.robot = robot
        if like is not None and like.settings().get("structure") == "transmission":
            self.structure_ = like  # its prior has zero drive terms: the tree's inertials only
        elif like is None and hasattr(robot, "make_structure"):
            self.structure_ = robot.make_structure(None)
        else:
            self.structure_ = (ModelStructure(robot, joint_terms=("armature",)) if like is None
                               else dataclasses.replace(like, joint_terms=("armature",)))
        self.parameters_ = self.structure_.prior()

    def fit(self, data=None) -> "CADModel":
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        return self.structure_.torques(self.parameters_, traj)


def load_parameters(result_json: str | Path, robot: Robot) -> tuple[ModelStructure, np.ndarray]:
    """Rebuild (structure, parameters) from a ``result.json`` written by ``sensorless identify``."""
    path = Path(result_json)
    try:
        doc = json.loads(path.read_text())
        settings = doc["settings"]
        values = doc["parameters"]
    except (OSError, ValueError, KeyError) as exc:
        raise SensorlessError(f"{path}: not a sensorless result file ({exc})") from None
    if settings.get("structure") == "transmission":
        from .regressor.transmission import TransmissionStructure

        tree = getattr(robot, "tree", None)
        if tree is None:
            raise SensorlessError(f"{path}: a model of a coupled-joint robot ('{doc.get('robot', {}).get('name')}'); "
                                  f"load it with that robot (e.g. --robot dvrk_psm), not '{robot.name}'")
        lo, hi = robot.position_limits()
        structure = TransmissionStructure.from_settings(tree, settings, limits=(lo, hi),
                                                        velocity_limits=robot.velocity_limits(), name=robot.name)
        structure.robot.factory = getattr(robot, "factory", None)
        return structure, _values(path, doc, structure, robot)
    if hasattr(robot, "make_structure"):
        raise SensorlessError(f"{path}: identified for '{doc.get('robot', {}).get('name')}' (per-joint model), "
                              f"not for the coupled-joint robot '{robot.name}'")
    common = {"joint_terms": tuple(settings["joint_terms"]), "coulomb_smoothing": settings.get("coulomb_smoothing", 0.0)}
    if settings.get("contact_frames"):
        from .regressor.contact import ContactStructure

        structure = ContactStructure(
            robot, **common, contact_frames=tuple(settings["contact_frames"]),
            contact_dims=tuple(settings.get("contact_dims", ())), mode=settings.get("contact_mode", "projected"),
            rcond=settings.get("rcond", 1e-7), contact_offset=settings.get("contact_offset", 0.0),
        )
    else:
        structure = ModelStructure(robot, **common, rows=settings.get("rows"))
    return structure, _values(path, doc, structure, robot)


def _values(path: Path, doc: dict, structure: ModelStructure, robot) -> np.ndarray:
    values = doc["parameters"]
    missing = [lab for lab in structure.labels if lab not in values]
    if missing:
        raise SensorlessError(
            f"{path}: parameters {missing[:5]} are missing; was it identified for another robot "
            f"(file says '{doc.get('robot', {}).get('name')}', given '{robot.name}')?"
        )
    return np.array([values[lab] for lab in structure.labels])

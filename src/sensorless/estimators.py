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
from .errors import ParameterError, SensorlessError
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
                               else dataclasses.replace(like, joint_terms=("armature",), per_joint_terms=None,
                                                   stribeck_velocity=None))
        self.parameters_ = self.structure_.prior()

    def fit(self, data=None) -> "CADModel":
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        return self.structure_.torques(self.parameters_, traj)


def load_parameters(result_json: str | Path, robot: Robot) -> tuple[ModelStructure, np.ndarray]:
    """Rebuild (structure, parameters) from a ``result.json`` written by ``sensorless identify``.

    A file that is not such a result (unreadable, not JSON, missing or mistyped keys,
    parameters that are not finite numbers) raises :class:`~sensorless.errors.ParameterError`.
    """
    path = Path(result_json)
    try:
        doc = json.loads(path.read_text())
        settings = doc["settings"]
        values = doc["parameters"]
        if not isinstance(settings, dict) or not isinstance(values, dict):
            raise TypeError("'settings' and 'parameters' must be objects")
        structure = _structure_from_settings(settings, doc, robot)
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError) as exc:
        if isinstance(exc, SensorlessError):
            raise ParameterError(f"{path}: {exc}") from None
        raise ParameterError(f"{path}: not a sensorless result file ({type(exc).__name__}: {exc})") from None
    except SensorlessError as exc:
        raise ParameterError(f"{path}: settings do not fit robot '{robot.name}': {exc}") from None
    missing = [lab for lab in structure.labels if lab not in values]
    if missing:
        name = doc.get("robot", {}).get("name") if isinstance(doc.get("robot"), dict) else None
        raise ParameterError(
            f"{path}: parameters {missing[:5]} are missing; was it identified for another robot "
            f"(file says '{name}', given '{robot.name}')?"
        )
    bad = [lab for lab in structure.labels
           if isinstance(values[lab], bool) or not isinstance(values[lab], (int, float))
           or not np.isfinite(values[lab])]
    if bad:
        raise ParameterError(f"{path}: parameter(s) {bad[:5]} are not finite numbers "
                             f"(e.g. {bad[0]} = {values[bad[0]]!r})")
    return structure, np.array([float(values[lab]) for lab in structure.labels])


def _structure_from_settings(settings: dict, doc: dict, robot: Robot) -> ModelStructure:
    file_robot = doc.get("robot", {}).get("name") if isinstance(doc.get("robot"), dict) else None
    if settings.get("structure") == "transmission":
        from .regressor.transmission import TransmissionStructure

        tree = getattr(robot, "tree", None)
        if tree is None:
            raise ParameterError(f"a model of a coupled-joint robot ('{file_robot}'); "
                                 f"load it with that robot (e.g. --robot dvrk_psm), not '{robot.name}'")
        lo, hi = robot.position_limits()
        structure = TransmissionStructure.from_settings(tree, settings, limits=(lo, hi),
                                                        velocity_limits=robot.velocity_limits(), name=robot.name)
        structure.robot.factory = getattr(robot, "factory", None)
        return structure
    terms = settings["joint_terms"]
    if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
        raise TypeError(f"settings.joint_terms must be a list of names, got {terms!r}")
    eps = settings.get("coulomb_smoothing", 0.0)
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not (np.isfinite(eps) and eps >= 0):
        raise TypeError(f"settings.coulomb_smoothing must be a number >= 0, got {eps!r}")
    if hasattr(robot, "make_structure"):
        raise ParameterError(f"identified for '{file_robot}' (per-joint model), "
                             f"not for the coupled-joint robot '{robot.name}'")
    common = {"joint_terms": tuple(terms), "coulomb_smoothing": float(eps)}
    by_joint = settings.get("joint_terms_by_joint")
    if by_joint is not None:
        if not isinstance(by_joint, dict) or not all(isinstance(t, list) for t in by_joint.values()):
            raise TypeError(f"settings.joint_terms_by_joint must map joints to lists of terms, got {by_joint!r}")
        common["per_joint_terms"] = {j: tuple(t) for j, t in by_joint.items()}
    for key, name in (("coulomb_smoothing_by_joint", "coulomb_smoothing"), ("stribeck_velocity", "stribeck_velocity"),
                      ("rest_velocity", "rest_velocity")):
        val = settings.get(key)
        if val is not None:
            if not isinstance(val, dict):
                raise TypeError(f"settings.{key} must map joints to numbers, got {val!r}")
            common[name] = val
    if settings.get("contact_frames"):
        from .regressor.contact import ContactStructure

        return ContactStructure.from_settings(robot, settings, **common)
    rows = settings.get("rows")
    if rows not in (None, "actuated", "all"):
        raise TypeError(f"settings.rows must be 'actuated' or 'all', got {rows!r}")
    return ModelStructure(robot, **common, rows=rows)

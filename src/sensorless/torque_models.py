"""Torque models with one scikit-learn-style interface, so comparisons are one loop.

    model.fit(trajectories) -> model
    model.predict(trajectory) -> τ̂ (N, n_rows)
    model.score(trajectory) -> TorqueMetrics        (one scoring function: :func:`score`)

:class:`TorqueModel` is the abstract base. It follows scikit-learn's estimator rules:
hyper-parameters are the ``__init__`` arguments, stored unchanged under their own names;
learned state goes in attributes ending in ``_``, set by ``fit``; ``get_params(deep)`` and
``set_params(**params)`` read and write the hyper-parameters, so ``sklearn.base.clone``
gives an unfitted copy.
"""

from __future__ import annotations

import dataclasses
import inspect
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from .data.trajectory import Trajectory
from .errors import ParameterError, SensorlessError
from .identification.identify import identify
from .identification.metrics import TorqueMetrics, torque_metrics
from .regressor.terms import ModelStructure
from .robot import Robot

__all__ = ["TorqueModel", "PhysicalModel", "CADModel", "load_parameters", "score"]


def score(model: "TorqueModel", traj: Trajectory) -> TorqueMetrics:
    """The one scoring function: per-row RMSE/NRMSE/R² of ``model.predict(traj)`` against
    the measured rows ``model.target(traj)`` (:func:`~sensorless.identification.torque_metrics`)."""
    from .identification.metrics import static_rows

    rows = model.row_names()
    return torque_metrics(model.target(traj), model.predict(traj), rows, static=static_rows(traj, rows))


class TorqueModel(ABC):
    """Abstract torque model: ``fit(trajectories) -> self``, ``predict(trajectory) -> τ̂``,
    ``score(trajectory) -> TorqueMetrics``, and scikit-learn's ``get_params``/``set_params``."""

    @abstractmethod
    def fit(self, data: Trajectory | Iterable[Trajectory]) -> "TorqueModel":
        """Learn from ``data``; returns ``self``."""

    @abstractmethod
    def predict(self, traj: Trajectory) -> np.ndarray:
        """Predicted rows (N, n_rows) for ``traj``."""

    def target(self, traj: Trajectory) -> np.ndarray:
        """The measured rows ``predict`` estimates (default: ``structure_.target``)."""
        return self.structure_.target(traj)

    def row_names(self) -> list[str]:
        """Names of the predicted rows."""
        return list(self.structure_.row_names)

    def score(self, traj: Trajectory) -> TorqueMetrics:
        """Per-row metrics of the prediction against the measured rows (:func:`score`)."""
        return score(self, traj)

    # ---- scikit-learn's parameter protocol ------------------------------------------------
    @classmethod
    def _init_signature(cls) -> tuple[list[str], str | None]:
        """(named ``__init__`` parameters, name of the stored ``**kwargs`` dict or None).

        A ``**kwargs`` parameter literally named ``kwargs`` is forwarded to the parent class's
        ``__init__``, whose parameters are then collected too; any other name (e.g.
        ``train_options``) is a dict of extra hyper-parameters stored under that name."""
        names: list[str] = []
        for klass in cls.__mro__:
            if "__init__" not in vars(klass) or klass is TorqueModel:
                continue
            params = list(inspect.signature(vars(klass)["__init__"]).parameters.values())[1:]
            if any(p.kind is p.VAR_POSITIONAL for p in params):
                raise SensorlessError(f"{klass.__name__}.__init__ must not take *args (scikit-learn's estimator rules)")
            names += [p.name for p in params if p.kind is not p.VAR_KEYWORD and p.name not in names]
            var = next((p.name for p in params if p.kind is p.VAR_KEYWORD), None)
            if var != "kwargs":
                return names, var
        return names, None

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The hyper-parameters, as given to ``__init__`` (``**kwargs`` flattened in); with
        ``deep``, those of nested models too as ``name__param``."""
        names, var = self._init_signature()
        out = {n: getattr(self, n, None) for n in names}
        if var is not None:
            out.update(getattr(self, var))
        if deep:
            for name, value in list(out.items()):
                if hasattr(value, "get_params") and not isinstance(value, type):
                    out.update({f"{name}__{k}": v for k, v in value.get_params(deep=True).items()})
        return out

    def set_params(self, **params) -> "TorqueModel":
        """Set hyper-parameters (``name`` or nested ``name__param``); returns ``self``."""
        names, var = self._init_signature()
        nested: dict[str, dict] = {}
        for key, value in params.items():
            head, sep, rest = key.partition("__")
            if sep:
                nested.setdefault(head, {})[rest] = value
            elif key in names:
                setattr(self, key, value)
            elif var is not None:
                getattr(self, var)[key] = value
            else:
                raise ParameterError(f"{type(self).__name__} has no hyper-parameter '{key}'; it has {names}")
        for head, sub in nested.items():
            if head not in names or not hasattr(getattr(self, head), "set_params"):
                raise ParameterError(f"{type(self).__name__}: '{head}' is not a nested model")
            getattr(self, head).set_params(**sub)
        return self

    def __repr__(self) -> str:
        names, _ = self._init_signature()
        args = ", ".join(f"{n}={v!r}" for n, v in self.get_params(deep=False).items() if n in names and not isinstance(v, Robot))
        return f"{type(self).__name__}({args})"


class PhysicalModel(TorqueModel):
    """Identified rigid-body model + joint terms (see :func:`sensorless.identification.identify`).

    ``structure``: identify with this structure (default: ``ModelStructure(robot, joint_terms)``,
    or the robot's own ``make_structure``). ``parameters``: a fixed parameter vector in that
    structure's layout; ``fit`` then keeps it and identifies nothing
    (:meth:`from_parameters`). ``friction``: keyword arguments of
    :func:`~sensorless.identification.friction_search.identify_friction` (noise-aware Coulomb smoothing,
    Stribeck search); ``fit`` then identifies through it, ``structure_`` is the structure it
    settled on and ``friction_fit_`` its record. ``fit`` also takes precompressed
    :class:`~sensorless.regressor.normal_equations.NormalEquations` (not with ``friction``).
    """

    def __init__(
        self,
        robot: Robot | None = None,
        method: str = "ols",
        joint_terms: Sequence[str] = ("fv", "fc", "offset", "armature"),
        *,
        structure: ModelStructure | None = None,
        parameters: np.ndarray | None = None,
        friction: dict | None = None,
        **identify_kwargs,
    ) -> None:
        self.robot = robot
        self.method = method
        self.joint_terms = joint_terms
        self.structure = structure
        self.parameters = parameters
        self.friction = friction
        self.identify_kwargs = identify_kwargs

    @classmethod
    def from_parameters(cls, structure: ModelStructure, parameters: np.ndarray) -> "PhysicalModel":
        """A fitted model with fixed parameters: τ̂ = W(q, q̇, q̈) π (e.g. from :func:`load_parameters`)."""
        return cls(structure.robot, structure=structure, parameters=parameters).fit()

    def _structure_to_fit(self) -> ModelStructure:
        if self.structure is not None:
            return self.structure
        if self.robot is None:
            raise ParameterError("PhysicalModel needs a robot or a structure")
        joint_terms = tuple(self.joint_terms)
        make = getattr(self.robot, "make_structure", None)  # a transmission's coordinate robot (e.g. the PSM)
        return make(joint_terms) if make else ModelStructure(self.robot, joint_terms=joint_terms)

    def fit(self, data=None) -> "PhysicalModel":
        self.structure_ = self._structure_to_fit()
        if self.parameters is not None:
            params = np.asarray(self.parameters, dtype=float)
            if params.shape != (self.structure_.n_params,):
                raise ParameterError(f"expected {self.structure_.n_params} parameters, got {params.shape}")
            self.parameters_ = params
            return self
        if data is None:
            raise ParameterError("PhysicalModel.fit needs trajectories (or fixed parameters=)")
        kwargs = dict(method=self.method, **self.identify_kwargs)
        if self.friction is not None:
            from .identification.friction_search import identify_friction

            self.result_, self.friction_fit_ = identify_friction(self.structure_, data, identify_kwargs=kwargs,
                                                                 **self.friction)
            self.structure_ = self.result_.structure
        else:
            self.result_ = identify(self.structure_, data, **kwargs)
        self.parameters_ = self.result_.parameters
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        return self.structure_.torques(self.parameters_, traj)


class CADModel(TorqueModel):
    """The robot model file as it is (its inertials and armature, no friction): the baseline.

    ``like``: score on the same equations as this structure (e.g. a contact projection).
    Nothing is learned from data; ``fit()`` builds ``structure_`` and ``parameters_`` (the prior).
    """

    def __init__(self, robot: Robot, like: ModelStructure | None = None) -> None:
        self.robot = robot
        self.like = like

    def fit(self, data=None) -> "CADModel":
        like, robot = self.like, self.robot
        if like is not None and like.settings().get("structure") == "transmission":
            self.structure_ = like  # its prior has zero drive terms: the tree's inertials only
        elif like is None and robot.coupled:
            self.structure_ = robot.make_structure(None)
        else:
            self.structure_ = (ModelStructure(robot, joint_terms=("armature",)) if like is None
                               else dataclasses.replace(like, joint_terms=("armature",), per_joint_terms=None,
                                                   stribeck_velocity=None))
        self.parameters_ = self.structure_.prior()
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        return self.structure_.torques(self.parameters_, traj)


def load_parameters(result_json: str | Path, robot: Robot) -> tuple[ModelStructure, np.ndarray]:
    """Rebuild (structure, parameters) from a ``result.json`` written by ``sensorless identify`` (or its folder).

    Read and validated by :func:`sensorless.identification.artifact.load_model_folder`: a file
    that is not such a result (unreadable, a FIFO, not JSON, missing or mistyped keys, parameters
    that are not finite or not physical) raises :class:`~sensorless.errors.ParameterError`.
    """
    from .identification.artifact import load_model_folder

    art = load_model_folder(result_json, robot)
    return art.structure, art.parameters

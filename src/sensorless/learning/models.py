"""Learned torque models with the fit/predict interface of :mod:`sensorless.torque_models`.

* :class:`HybridModel` — physical model + learned residual:
  τ̂ = τ_phys(q, q̇, q̈) + r_θ(window of q, q̇; τ_phys). The network only learns what the
  physics misses (e.g. trocar / body-wall interaction), from a few minutes of data.
* :class:`LearnedTorqueModel` — pure-learning baseline: τ̂ = g_θ(window of q, q̇)
  over the whole workspace (MLP, or LSTM with ``kind="lstm"``).
* :class:`MLPTorqueModel` — configurable black box (default 5 × 2048, LeakyReLU) with
  user-supplied ``features(traj)`` and ``targets(traj)`` callables, e.g. actuation from
  a legged robot's sensor measurements.

All networks are trained by :func:`~sensorless.learning.mlp.train_network` (Adam,
ReduceLROnPlateau, early stopping on a block validation split, seeded) on standardised
inputs and targets, and saved as weights + JSON (:mod:`sensorless.learning.io`).
"""

from __future__ import annotations

import contextlib
from dataclasses import fields, replace
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..torque_models import PhysicalModel, TorqueModel
from ..errors import DataError, SensorlessError
from ..regressor.normal_equations import iter_trajectories
from ..regressor.terms import ModelStructure
from ..robot import Robot
from .features import Standardizer, WindowFeatures
from .io import load_network, save_network
from .mlp import (
    TrainConfig,
    build_network,
    deterministic_torch,
    predict_network,
    train_network,
)

__all__ = ["HybridModel", "LearnedTorqueModel", "MLPTorqueModel"]

FeatureFn = Callable[[Trajectory], np.ndarray]


def _train_config(train: TrainConfig | None, overrides: dict) -> TrainConfig:
    cfg = train or TrainConfig()
    names = {f.name for f in fields(TrainConfig)}
    bad = sorted(set(overrides) - names)
    if bad:
        raise SensorlessError(f"unknown training option(s) {bad}; known: {sorted(names)}")
    return replace(cfg, **overrides)


class _CallableFeatures:
    """Adapter giving a user feature function the WindowFeatures interface."""

    def __init__(self, fn: FeatureFn) -> None:
        self.fn, self.scaler = fn, Standardizer()

    def raw(self, traj: Trajectory, tau_model=None) -> np.ndarray:
        X = np.asarray(self.fn(traj), dtype=float)
        if X.ndim != 2 or X.shape[0] != len(traj):
            raise DataError(f"features(traj) must return ({len(traj)}, n_features), got {X.shape}", traj.source)
        return X

    def fit_transform(self, trajs, taus=None) -> np.ndarray:
        X = np.vstack([self.raw(t) for t in trajs])
        self.scaler.fit(X)
        return self.scaler.transform(X)

    def transform(self, traj, tau_model=None) -> np.ndarray:
        return self.scaler.transform(self.raw(traj))

    def to_dict(self) -> dict:
        return {"callable": getattr(self.fn, "__qualname__", repr(self.fn)), "scaler": self.scaler.to_dict()}


class _Network(TorqueModel):
    """Shared machinery: standardise, build, train, predict, save/load a network.

    Training settings: ``train`` (a :class:`TrainConfig`) with ``train_options`` overriding
    its fields; both are hyper-parameters, :attr:`train_config` is what training uses."""

    @property
    def train_config(self) -> TrainConfig:
        return _train_config(self.train, self.train_options)

    def target(self, traj: Trajectory) -> np.ndarray:
        return self._target(traj)

    def row_names(self) -> list[str]:
        return list(self.output_names_)

    def _fit_xy(self, X: np.ndarray, Y: np.ndarray, hidden, activation: str, kind: str, window: int) -> None:
        self.y_scaler_ = Standardizer().fit(Y)
        self.architecture_ = {"kind": kind, "in_dim": int(X.shape[1]), "out_dim": int(Y.shape[1]),
                              "hidden": [int(h) for h in hidden], "activation": activation, "window": int(window)}
        cfg = self.train_config
        with deterministic_torch(cfg.seed, cfg.num_threads, cfg.deterministic):
            self.net_ = build_network(self.architecture_)
            self.history_ = train_network(self.net_, X, self.y_scaler_.transform(Y), cfg)

    def _predict_x(self, X: np.ndarray) -> np.ndarray:
        if not hasattr(self, "net_"):
            raise SensorlessError(f"{type(self).__name__} is not fitted; call fit() first")
        cfg = self.train_config
        with deterministic_torch(None, cfg.num_threads, cfg.deterministic):
            return self.y_scaler_.inverse(predict_network(self.net_, X))

    def _meta(self) -> dict:
        return {
            "type": type(self).__name__, "architecture": self.architecture_, "features": self.features_.to_dict(),
            "target_scaler": self.y_scaler_.to_dict(), "train": self.train_config.to_dict(),
            "history": {k: v for k, v in self.history_.items()}, "output_names": list(self.output_names_),
            "params": self._saved_params(),
        }

    def save(self, directory: str | Path) -> Path:
        """Weights (``weights.pt``) + architecture/normalisation/settings (``model.json``)."""
        if not hasattr(self, "net_"):
            raise SensorlessError(f"{type(self).__name__} is not fitted; nothing to save")
        return save_network(directory, self.net_, self._meta())

    def _restore(self, net, meta: dict, features) -> None:
        self.net_, self.architecture_ = net, meta["architecture"]
        self.features_ = features
        self.y_scaler_ = Standardizer.from_dict(meta["target_scaler"])
        self.history_ = meta.get("history", {})
        self.output_names_ = list(meta["output_names"])
        self.train, self.train_options = TrainConfig(**meta["train"]), {}

    def _saved_params(self) -> dict:  # pragma: no cover - overridden
        """The hyper-parameters written to model.json (JSON types)."""
        return {}


@contextlib.contextmanager
def _meta_errors(directory):
    """A model.json that parses but lacks or mistypes a key → DataError naming the directory."""
    try:
        yield
    except SensorlessError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise DataError(f"saved model description is incomplete or malformed ({type(exc).__name__}: {exc})",
                        str(directory)) from None


def _check_type(meta: dict, expected: str, directory) -> None:
    if not isinstance(meta, dict):
        raise DataError("saved model description is not a JSON object", str(directory))
    if meta.get("type") != expected:
        raise DataError(f"saved model is a {meta.get('type')!r}, not a {expected}", str(directory))


class MLPTorqueModel(_Network):
    """Black-box network: ``features(traj)`` → ``targets(traj)``.

    Defaults: 5 hidden layers × 2048, LeakyReLU; features = causal window of q, q̇
    (``window`` samples); targets = ``traj.tau``. Pass ``features``/``targets`` callables
    returning (N, ·) arrays to feed other measurements (e.g. IMU, contact states) or to
    predict other quantities. ``per_joint=True`` gives one network per output.
    Training options: ``train=TrainConfig(...)`` and/or keyword overrides (epochs=…).
    """

    def __init__(
        self,
        hidden: Sequence[int] = (2048,) * 5,
        activation: str = "leakyrelu",
        *,
        features: FeatureFn | None = None,
        targets: FeatureFn | None = None,
        window: int = 1,
        stride: int = 1,
        per_joint: bool = False,
        output_names: Sequence[str] | None = None,
        train: TrainConfig | None = None,
        **train_options,
    ) -> None:
        self.hidden, self.activation = hidden, activation
        self.features, self.targets = features, targets
        self.window, self.stride, self.per_joint = window, stride, per_joint
        self.output_names = output_names
        self.train, self.train_options = train, train_options
        _train_config(train, train_options)  # unknown options fail here, nothing is changed

    def _saved_params(self) -> dict:
        return {"hidden": [int(h) for h in self.hidden], "activation": self.activation, "window": self.window, "stride": self.stride,
                "per_joint": self.per_joint, "features": getattr(self.features, "__qualname__", None),
                "targets": getattr(self.targets, "__qualname__", None)}

    # -- hooks -------------------------------------------------------------------
    def _new_features(self):
        return _CallableFeatures(self.features) if self.features is not None else WindowFeatures(self.window, self.stride)

    def _target(self, traj: Trajectory) -> np.ndarray:
        if self.targets is not None:
            Y = np.asarray(self.targets(traj), dtype=float)
        elif traj.tau is None:
            raise DataError("trajectory has no torque/effort ('tau') to learn", traj.source)
        else:
            Y = traj.tau
        if Y.ndim != 2 or Y.shape[0] != len(traj):
            raise DataError(f"targets must be ({len(traj)}, n_outputs), got {Y.shape}", traj.source)
        return Y

    def _names(self, traj: Trajectory, n_out: int) -> list[str]:
        if self.output_names is not None:
            return list(self.output_names)
        if self.targets is None and n_out == traj.n_joints:
            return list(traj.joint_names)
        return [f"y{i}" for i in range(n_out)]

    def _kind(self) -> str:
        return "per_joint" if self.per_joint else "mlp"

    # -- interface ---------------------------------------------------------------
    def fit(self, data: Trajectory | Iterable[Trajectory]) -> MLPTorqueModel:
        trajs = list(iter_trajectories(data))
        if not trajs:
            raise DataError("no trajectory was given")
        self.features_ = self._new_features()
        X = self.features_.fit_transform(trajs)
        Y = np.vstack([self._target(t) for t in trajs])
        self.output_names_ = self._names(trajs[0], Y.shape[1])
        self._fit_xy(X, Y, self.hidden, self.activation, self._kind(), self.window)
        return self

    def predict(self, traj: Trajectory) -> np.ndarray:
        if not hasattr(self, "features_"):
            raise SensorlessError(f"{type(self).__name__} is not fitted; call fit() first")
        return self._predict_x(self.features_.transform(traj))

    @classmethod
    def load(cls, directory: str | Path, features: FeatureFn | None = None, targets: FeatureFn | None = None) -> MLPTorqueModel:
        """Load a saved model; custom ``features``/``targets`` callables must be given again."""
        net, meta = load_network(directory)
        _check_type(meta, cls.__name__, directory)
        with _meta_errors(directory):
            p = meta["params"]
            if p.get("features") and features is None:
                raise DataError(f"this model was trained with features={p['features']}; pass the same callable to load()", str(directory))
            obj = cls.__new__(cls)
            obj._init_from_params(p, features, targets)
            f = _CallableFeatures(features) if features is not None else WindowFeatures.from_dict(meta["features"])
            if features is not None:
                f.scaler = Standardizer.from_dict(meta["features"]["scaler"])
            obj._restore(net, meta, f)
            return obj

    def _init_from_params(self, p: dict, features, targets) -> None:
        MLPTorqueModel.__init__(self, p["hidden"], p["activation"], features=features, targets=targets,
                                window=p["window"], stride=p["stride"], per_joint=p["per_joint"])


class LearnedTorqueModel(MLPTorqueModel):
    """Pure-learning baseline: joint torques from a causal window of q, q̇ (no physics).

    With ``robot`` the targets are its actuated joints' efforts in model order (same rows
    as :class:`~sensorless.torque_models.PhysicalModel`). ``kind``: "mlp" (default, 2 × 256
    ReLU) or "lstm" (``hidden=(h,)`` LSTM units over the window).
    """

    def __init__(
        self,
        robot: Robot | None = None,
        *,
        window: int = 10,
        stride: int = 1,
        hidden: Sequence[int] = (256, 256),
        activation: str = "relu",
        kind: str = "mlp",
        per_joint: bool = False,
        train: TrainConfig | None = None,
        **train_options,
    ) -> None:
        if kind not in ("mlp", "lstm"):
            raise SensorlessError(f"unknown kind '{kind}'; choose 'mlp' or 'lstm'")
        super().__init__(hidden, activation, window=window, stride=stride, per_joint=per_joint, train=train, **train_options)
        self.robot, self.kind = robot, kind

    def _saved_params(self) -> dict:
        return {**super()._saved_params(), "kind": self.kind}

    def _rows(self) -> ModelStructure:
        """The robot's actuated rows (targets in model order)."""
        if getattr(self, "structure_", None) is None:
            self.structure_ = ModelStructure(self.robot, joint_terms=())
        return self.structure_

    def _names(self, traj: Trajectory, n_out: int) -> list[str]:
        return list(self._rows().row_names) if self.robot is not None else super()._names(traj, n_out)

    def _kind(self) -> str:
        return "lstm" if self.kind == "lstm" else super()._kind()

    def _target(self, traj: Trajectory) -> np.ndarray:
        return self._rows().target(traj) if self.robot is not None else super()._target(traj)

    @classmethod
    def load(cls, directory: str | Path, robot: Robot | None = None) -> LearnedTorqueModel:  # type: ignore[override]
        net, meta = load_network(directory)
        _check_type(meta, cls.__name__, directory)
        with _meta_errors(directory):
            p = meta["params"]
            obj = cls(robot, window=p["window"], stride=p["stride"], hidden=p["hidden"], activation=p["activation"],
                      kind=p.get("kind", "mlp"), per_joint=p["per_joint"])
            obj._restore(net, meta, WindowFeatures.from_dict(meta["features"]))
            return obj


class HybridModel(_Network):
    """Physical model + learned residual: τ̂ = τ_phys + r_θ(window of q, q̇; τ_phys).

    ``physical_model``: the physical base, a :class:`~sensorless.torque_models.PhysicalModel`
    (fixed parameters: :meth:`~sensorless.torque_models.PhysicalModel.from_parameters`); any
    :class:`~sensorless.torque_models.TorqueModel` with ``predict`` and ``structure_`` (the target
    rows) is accepted. ``fit(data)`` trains
    the residual on ``data`` (e.g. a few minutes in the trocar). The physical model is fitted
    first on ``physical_data`` when given, or on ``data`` if it was never fitted
    (``fit_physical=True/False`` forces the choice).
    Residual network: ``hidden`` (default 2 × 256, ReLU), one net per joint by default.
    """

    def __init__(
        self,
        physical_model: PhysicalModel | TorqueModel,
        *,
        window: int = 10,
        stride: int = 1,
        hidden: Sequence[int] = (256, 256),
        activation: str = "relu",
        per_joint: bool = True,
        use_model_torque: bool = True,
        fit_physical: bool | None = None,
        train: TrainConfig | None = None,
        **train_options,
    ) -> None:
        self.physical_model = physical_model
        self.window, self.stride = window, stride
        self.hidden, self.activation = hidden, activation
        self.per_joint, self.use_model_torque, self.fit_physical = per_joint, use_model_torque, fit_physical
        self.train, self.train_options = train, train_options
        _train_config(train, train_options)  # unknown options fail here, nothing is changed

    def _saved_params(self) -> dict:
        return {"window": self.window, "stride": self.stride, "hidden": [int(h) for h in self.hidden], "activation": self.activation,
                "per_joint": self.per_joint, "use_model_torque": self.use_model_torque}

    @property
    def structure_(self) -> ModelStructure:
        """The physical model's structure (rows of the prediction)."""
        return self.physical_model.structure_

    def _target(self, traj: Trajectory) -> np.ndarray:
        s = getattr(self.physical_model, "structure_", None)
        if s is not None:
            return s.target(traj)
        if traj.tau is None:
            raise DataError("trajectory has no torque/effort ('tau')", traj.source)
        return traj.tau

    def _is_fitted(self) -> bool:
        return hasattr(self.physical_model, "structure_") and (
            hasattr(self.physical_model, "parameters_") or hasattr(self.physical_model, "net_"))

    def _fit_physical(self, data, physical_data) -> list[Trajectory]:
        """The training trajectories, after fitting the physical model when asked or needed."""
        trajs = list(iter_trajectories(data))
        if not trajs:
            raise DataError("no trajectory was given")
        if physical_data is not None or self.fit_physical:
            self.physical_model.fit(physical_data if physical_data is not None else trajs)
        elif not self._is_fitted():
            if self.fit_physical is False:
                raise SensorlessError("the physical model is not fitted (fit_physical=False)")
            self.physical_model.fit(trajs)
        return trajs

    def fit(self, data: Trajectory | Iterable[Trajectory], physical_data=None) -> HybridModel:
        trajs = self._fit_physical(data, physical_data)
        phys = [self.physical_model.predict(t) for t in trajs]
        Y = np.vstack([self._target(t) - p for t, p in zip(trajs, phys)])
        self.features_ = WindowFeatures(self.window, self.stride)
        X = self.features_.fit_transform(trajs, phys if self.use_model_torque else None)
        names = getattr(getattr(self.physical_model, "structure_", None), "row_names", None)
        self.output_names_ = list(names) if names is not None else [f"y{i}" for i in range(Y.shape[1])]
        self._fit_xy(X, Y, self.hidden, self.activation, "per_joint" if self.per_joint else "mlp", self.window)
        return self

    def predict_residual(self, traj: Trajectory, physical: np.ndarray | None = None) -> np.ndarray:
        """The learned correction r_θ (N, rows)."""
        if not hasattr(self, "features_"):
            raise SensorlessError("HybridModel is not fitted; call fit() first")
        if physical is None and self.use_model_torque:
            physical = self.physical_model.predict(traj)
        return self._predict_x(self.features_.transform(traj, physical if self.use_model_torque else None))

    def predict(self, traj: Trajectory) -> np.ndarray:
        phys = self.physical_model.predict(traj)
        return phys + self.predict_residual(traj, phys)

    @classmethod
    def load(cls, directory: str | Path, physical_model: PhysicalModel | TorqueModel) -> HybridModel:
        """Load a saved residual and attach it to ``physical_model`` (the one it was trained with)."""
        net, meta = load_network(directory)
        _check_type(meta, cls.__name__, directory)
        with _meta_errors(directory):
            p = meta["params"]
            obj = cls(physical_model, window=p["window"], stride=p["stride"], hidden=p["hidden"], activation=p["activation"],
                      per_joint=p["per_joint"], use_model_torque=p["use_model_torque"])
            obj._restore(net, meta, WindowFeatures.from_dict(meta["features"]))
            return obj

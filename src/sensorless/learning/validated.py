"""A hybrid residual validated on held-out data, so it cannot make that data worse.

:class:`ValidatedHybridModel` is a :class:`~sensorless.learning.HybridModel` whose residual
r_θ is

1. **early-stopped on held-out trajectories**: given several training trajectories, the
   last one (or ``validation=...``) is held out and training stops when its loss stops
   improving (best weights kept); the others are trained on. With a single trajectory the
   last ``val_fraction`` of it (one contiguous block) is held out and a
   :class:`~sensorless.errors.DataWarning` says so: one excitation trajectory rarely
   predicts how the residual does on another.
2. **scaled on the held-out data**, per output j: with e = y − τ_phys and r the residual
   on the held-out samples,

       α_j = clip(⟨r_j, e_j⟩ / ⟨r_j, r_j⟩, 0, 1),

   the minimiser of ‖e_j − α r_j‖² over [0, 1]. α_j is set to 0 unless the scaled residual
   lowers the held-out mean-square error by at least ``min_gain`` (relative), so
   τ̂ = τ_phys + α ⊙ r is never worse than τ_phys on the held-out data and falls back to
   the physical model where the residual does not transfer.
"""

from __future__ import annotations

import warnings
from typing import Iterable

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, DataWarning
from ..torque_models import PhysicalModel, TorqueModel
from ..regressor.normal_equations import iter_trajectories
from .features import Standardizer, WindowFeatures
from .mlp import build_network, deterministic_torch, train_network
from .models import HybridModel

__all__ = ["ValidatedHybridModel", "residual_scale"]


def residual_scale(err: np.ndarray, res: np.ndarray, min_gain: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(α, gain) per column: α = clip(⟨r, e⟩/⟨r, r⟩, 0, 1), gain = 1 − ‖e − α r‖²/‖e‖²;
    α = 0 where gain < ``min_gain``."""
    err, res = np.asarray(err, float), np.asarray(res, float)
    rr = np.einsum("ij,ij->j", res, res)
    re = np.einsum("ij,ij->j", res, err)
    alpha = np.clip(np.divide(re, rr, out=np.zeros_like(rr), where=rr > 0), 0.0, 1.0)
    ee = np.einsum("ij,ij->j", err, err)
    after = np.sum((err - alpha * res) ** 2, axis=0)
    gain = np.divide(ee - after, ee, out=np.zeros_like(ee), where=ee > 0)
    alpha = np.where(gain >= min_gain, alpha, 0.0)
    return alpha, np.where(alpha > 0, gain, 0.0)


class ValidatedHybridModel(HybridModel):
    """HybridModel with held-out early stopping and a held-out residual scale (module docstring).

    Extra hyper-parameters: ``val_fraction`` (held-out tail of a single trajectory),
    ``min_gain`` (relative held-out MSE reduction a residual must bring to be kept).
    Learned: ``scale_`` (α per output), ``validation_gain_`` (held-out MSE reduction per output),
    ``validation_`` (what was held out). The rest as :class:`HybridModel`.
    """

    def __init__(self, physical_model: PhysicalModel | TorqueModel, *, val_fraction: float = 0.3, min_gain: float = 0.02, **kwargs) -> None:
        """``kwargs``: :class:`HybridModel`'s hyper-parameters (part of ``get_params``)."""
        super().__init__(physical_model, **kwargs)
        self.val_fraction, self.min_gain = val_fraction, min_gain

    def _saved_params(self) -> dict:
        return {**super()._saved_params(), "val_fraction": float(self.val_fraction), "min_gain": float(self.min_gain)}

    def _split(self, trajs: list[Trajectory], validation) -> tuple[list[Trajectory], list[Trajectory], str]:
        if validation is not None:
            return trajs, list(iter_trajectories(validation)), "given"
        if len(trajs) >= 2:
            return trajs[:-1], trajs[-1:], f"trajectory {len(trajs) - 1} ({trajs[-1].source})"
        (one,) = trajs
        if not 0.0 < self.val_fraction < 1.0:
            raise DataError(f"val_fraction must be in (0, 1), got {self.val_fraction}", one.source)
        cut = int(round(len(one) * (1.0 - self.val_fraction)))
        warnings.warn(f"{one.source}: one training trajectory: the residual is validated on its last "
                      f"{self.val_fraction:.0%}; give several trajectories (or validation=...) so that early "
                      "stopping and the residual scale are chosen on a different trajectory", DataWarning,
                      stacklevel=3)
        return [one.take(slice(0, cut))], [one.take(slice(cut, None))], f"last {self.val_fraction:.0%} of {one.source}"

    def fit(self, data: Trajectory | Iterable[Trajectory], physical_data=None, *, validation=None) -> "ValidatedHybridModel":
        """Fit the physical model (as :meth:`HybridModel.fit`), then the residual on the training
        part with early stopping on the held-out part, then α on the held-out part."""
        trajs = self._fit_physical(data, physical_data)
        train, val, how = self._split(trajs, validation)
        use = self.use_model_torque
        p_tr = [self.physical_model.predict(t) for t in train]
        p_va = [self.physical_model.predict(t) for t in val]
        Y = np.vstack([self._target(t) - p for t, p in zip(train, p_tr)])
        E = np.vstack([self._target(t) - p for t, p in zip(val, p_va)])
        self.features_ = WindowFeatures(self.window, self.stride)
        X = self.features_.fit_transform(train, p_tr if use else None)
        Xv = np.vstack([self.features_.transform(t, p if use else None) for t, p in zip(val, p_va)])
        names = getattr(getattr(self.physical_model, "structure_", None), "row_names", None)
        self.output_names_ = list(names) if names is not None else [f"y{i}" for i in range(Y.shape[1])]
        self.y_scaler_ = Standardizer().fit(Y)
        self.architecture_ = {"kind": "per_joint" if self.per_joint else "mlp", "in_dim": int(X.shape[1]),
                              "out_dim": int(Y.shape[1]), "hidden": [int(h) for h in self.hidden],
                              "activation": self.activation, "window": int(self.window)}
        cfg = self.train_config
        with deterministic_torch(cfg.seed, cfg.num_threads, cfg.deterministic):
            self.net_ = build_network(self.architecture_)
            self.history_ = train_network(self.net_, X, self.y_scaler_.transform(Y), cfg,
                                          validation=(Xv, self.y_scaler_.transform(E)))
        R = self._predict_x(Xv)
        self.scale_, self.validation_gain_ = residual_scale(E, R, self.min_gain)
        self.validation_ = {"held_out": how, "n_samples": int(E.shape[0]),
                            "scale": dict(zip(self.output_names_, map(float, self.scale_))),
                            "gain": dict(zip(self.output_names_, map(float, self.validation_gain_)))}
        self.history_["validation"] = self.validation_
        return self

    def predict_residual(self, traj: Trajectory, physical: np.ndarray | None = None) -> np.ndarray:
        """α ⊙ r_θ (N, rows): the learned correction scaled by the held-out residual scale."""
        scale = getattr(self, "scale_", None)
        r = super().predict_residual(traj, physical)
        return r if scale is None else r * scale

    def _meta(self) -> dict:
        return {**super()._meta(), "scale": [float(a) for a in self.scale_]}

    @classmethod
    def load(cls, directory, physical_model) -> "ValidatedHybridModel":
        from .io import load_network

        obj = super().load.__func__(cls, directory, physical_model)
        _, meta = load_network(directory)
        obj.scale_ = np.asarray(meta["scale"], float)
        p = meta["params"]
        obj.val_fraction, obj.min_gain = float(p["val_fraction"]), float(p["min_gain"])
        return obj

"""Causal window features for learned torque models.

Row i of the feature matrix holds, for samples i − (W−1)s, …, i − s, i (oldest first;
W = ``window``, s = ``stride``), the positions and velocities of all joints, followed by
the model's predicted torque at sample i when given:

    x_i = [q_{i−(W−1)s}, q̇_{i−(W−1)s}, …, q_i, q̇_i, τ_model,i]

Only past and present samples enter (causal); the first (W−1)s rows repeat the first
sample as history. The windows are strided views (``sliding_window_view``), no loop.
Inputs are standardised column-wise with statistics fitted on training data and stored
with the model (:class:`Standardizer`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, ShapeMismatchError

__all__ = ["Standardizer", "WindowFeatures", "sliding_window"]


def sliding_window(x: np.ndarray, window: int, stride: int = 1) -> np.ndarray:
    """Causal windows of ``x`` (N, k) → (N, window·k), oldest sample first, edge-padded."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2:
        raise ShapeMismatchError(f"sliding_window needs a 2-D array (samples, channels), got shape {x.shape}")
    if window < 1 or stride < 1:
        raise DataError(f"window and stride must be >= 1, got window={window}, stride={stride}")
    N, k = x.shape
    if N == 0:
        return np.zeros((0, window * k))
    span = (window - 1) * stride
    xp = np.concatenate([np.repeat(x[:1], span, axis=0), x]) if span else x
    w = np.lib.stride_tricks.sliding_window_view(xp, span + 1, axis=0)[:, :, ::stride]  # (N, k, window)
    return np.ascontiguousarray(w.transpose(0, 2, 1)).reshape(N, window * k)


@dataclass
class Standardizer:
    """Column-wise (x − mean) / std; constant columns keep std = 1."""

    mean: np.ndarray | None = None
    std: np.ndarray | None = None

    def fit(self, X: np.ndarray) -> Standardizer:
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[0] < 2:
            raise DataError(f"need at least 2 samples to fit normalisation statistics, got shape {X.shape}")
        if not np.all(np.isfinite(X)):
            r, c = np.argwhere(~np.isfinite(X))[0]
            raise DataError(f"non-finite training value at sample {r}, column {c}")
        self.mean = X.mean(axis=0)
        std = X.std(axis=0)
        self.std = np.where(std > 1e-12 * max(1.0, float(np.abs(self.mean).max(initial=0))), std, 1.0)
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        self._check(X)
        return (np.asarray(X, dtype=float) - self.mean) / self.std

    def inverse(self, Z: np.ndarray) -> np.ndarray:
        self._check(Z)
        return np.asarray(Z, dtype=float) * self.std + self.mean

    def _check(self, X: np.ndarray) -> None:
        if self.mean is None:
            raise DataError("normalisation statistics are not fitted")
        if np.shape(X)[-1] != self.mean.shape[0]:
            raise ShapeMismatchError(f"expected {self.mean.shape[0]} columns, got {np.shape(X)[-1]}")

    def to_dict(self) -> dict:
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> Standardizer:
        return cls(np.asarray(d["mean"], dtype=float), np.asarray(d["std"], dtype=float))


@dataclass
class WindowFeatures:
    """Feature map of a trajectory: windows of q and q̇ (+ the model torque).

    ``joints``: the joint order of the columns (fixed at the first ``build``; a later
    trajectory is reordered by name, JointNameError-style errors if a joint is missing).
    """

    window: int = 10
    stride: int = 1
    use_q: bool = True
    use_v: bool = True
    joints: tuple[str, ...] | None = None
    scaler: Standardizer = field(default_factory=Standardizer)

    def raw(self, traj: Trajectory, tau_model: np.ndarray | None = None) -> np.ndarray:
        """Unnormalised features (N, n_features)."""
        if self.joints is None:
            self.joints = tuple(traj.joint_names)
        missing = [j for j in self.joints if j not in traj.joint_names]
        if missing:
            raise DataError(f"trajectory lacks joint(s) {missing} the features were built with", traj.source)
        if tuple(traj.joint_names) != self.joints:
            traj = traj.select_joints(list(self.joints))
        chans = []
        if self.use_q:
            chans.append(traj.q)
        if self.use_v:
            if traj.v is None:
                raise DataError("trajectory has no velocity 'v' (compute it with savgol_derivatives)", traj.source)
            chans.append(traj.v)
        if not chans:
            raise DataError("WindowFeatures needs use_q or use_v")
        X = sliding_window(np.hstack(chans), self.window, self.stride)
        if tau_model is not None:
            tau_model = np.asarray(tau_model, dtype=float)
            if tau_model.shape[0] != X.shape[0]:
                raise ShapeMismatchError(f"model torque has {tau_model.shape[0]} samples, trajectory {X.shape[0]}", traj.source)
            X = np.hstack([X, tau_model])
        return X

    def fit_transform(self, trajs: Sequence[Trajectory], taus: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
        """Raw features of several trajectories (windows never cross trajectories), fit the scaler."""
        taus = taus if taus is not None else [None] * len(trajs)
        X = np.vstack([self.raw(tr, ta) for tr, ta in zip(trajs, taus)])
        self.scaler.fit(X)
        return self.scaler.transform(X)

    def transform(self, traj: Trajectory, tau_model: np.ndarray | None = None) -> np.ndarray:
        return self.scaler.transform(self.raw(traj, tau_model))

    def to_dict(self) -> dict:
        return {
            "window": self.window, "stride": self.stride, "use_q": self.use_q, "use_v": self.use_v,
            "joints": list(self.joints) if self.joints is not None else None, "scaler": self.scaler.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> WindowFeatures:
        return cls(int(d["window"]), int(d["stride"]), bool(d["use_q"]), bool(d["use_v"]),
                   tuple(d["joints"]) if d.get("joints") else None, Standardizer.from_dict(d["scaler"]))

"""Torque-error metrics, per joint.

* RMSE_j = sqrt(mean_i (τ̂_ij − τ_ij)²)
* NRMSE_j = RMSE_j / (max_i τ_ij − min_i τ_ij)       (fraction of the measured range; dVRK convention)
* relative RMS_j = RMSE_j / sqrt(mean_i τ_ij²)
* bias_j = mean_i (τ̂_ij − τ_ij)

A joint that does not move in the log (``static``: position range below 1e-3) has a torque range
made of current noise: its NRMSE is meaningless and is not reported (None, with the reason);
RMSE and bias in N·m are. The mean NRMSE is over the joints that move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TorqueMetrics", "torque_metrics", "metrics_from_sums", "static_rows"]


@dataclass
class TorqueMetrics:
    joints: list[str]
    rmse: np.ndarray
    nrmse: np.ndarray
    rel_rms: np.ndarray
    n_samples: int
    bias: np.ndarray | None = None
    static: np.ndarray | None = None  # (n_joints,) bool: the joint does not move in the log

    STATIC_NOTE = "the joint does not move in this log: its torque range is noise, so NRMSE is not shown"

    def to_dict(self) -> dict:
        static = np.zeros(len(self.joints), bool) if self.static is None else np.asarray(self.static, bool)
        per = {}
        for k, j in enumerate(self.joints):
            d = {"rmse": float(self.rmse[k]), "nrmse": None if static[k] else float(self.nrmse[k]),
                 "rel_rms": float(self.rel_rms[k])}
            if self.bias is not None:
                d["bias"] = float(self.bias[k])
            if static[k]:
                d.update(static=True, note=self.STATIC_NOTE)
            per[j] = d
        moving = self.nrmse[~static]
        return {
            "per_joint": per,
            "mean_rmse": float(np.mean(self.rmse)),
            "mean_nrmse": float(np.mean(moving)) if moving.size else None,
            "mean_rel_rms": float(np.mean(self.rel_rms)),
            "n_samples": self.n_samples,
            **({"static_joints": [j for j, st in zip(self.joints, static) if st]} if static.any() else {}),
        }


def _safe_div(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.divide(a, b, out=np.full_like(a, np.nan), where=b > 0)


def metrics_from_sums(joints, sse, y_sq, y_range, n) -> TorqueMetrics:
    rmse = np.sqrt(np.asarray(sse) / max(n, 1))
    rms = np.sqrt(np.asarray(y_sq) / max(n, 1))
    return TorqueMetrics(list(joints), rmse, _safe_div(rmse, np.asarray(y_range, float)), _safe_div(rmse, rms), int(n))


def torque_metrics(measured: np.ndarray, predicted: np.ndarray, joints, static=None) -> TorqueMetrics:
    """Metrics of predicted vs measured effort, arrays (N, n_joints); ``static``: per joint, whether
    it does not move in the log (module docstring)."""
    measured = np.asarray(measured, float)
    err = np.asarray(predicted, float) - measured
    rng = measured.max(axis=0) - measured.min(axis=0)
    m = metrics_from_sums(joints, (err**2).sum(0), (measured**2).sum(0), rng, measured.shape[0])
    m.bias = err.mean(axis=0) if len(err) else np.full(err.shape[1], np.nan)
    m.static = None if static is None else np.asarray(static, bool)
    return m


def static_rows(traj, rows) -> np.ndarray | None:
    """Per row named like a joint of ``traj``: its position range in the log is below 1e-3 (at rest);
    None when the rows are not joints (e.g. a contact projection)."""
    names = list(traj.joint_names)
    if traj.q is None or not all(r in names for r in rows) or not len(traj):
        return None
    q = np.asarray(traj.q)[:, [names.index(r) for r in rows]]
    return np.ptp(q, axis=0) < 1e-3

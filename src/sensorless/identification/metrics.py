"""Torque-error metrics, per joint.

* RMSE_j = sqrt(mean_i (τ̂_ij − τ_ij)²)
* NRMSE_j = RMSE_j / (max_i τ_ij − min_i τ_ij)       (fraction of the measured range; dVRK convention)
* relative RMS_j = RMSE_j / sqrt(mean_i τ_ij²)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TorqueMetrics", "torque_metrics", "metrics_from_sums"]


@dataclass
class TorqueMetrics:
    joints: list[str]
    rmse: np.ndarray
    nrmse: np.ndarray
    rel_rms: np.ndarray
    n_samples: int

    def to_dict(self) -> dict:
        per = {
            j: {"rmse": float(a), "nrmse": float(b), "rel_rms": float(c)}
            for j, a, b, c in zip(self.joints, self.rmse, self.nrmse, self.rel_rms)
        }
        return {
            "per_joint": per,
            "mean_rmse": float(np.mean(self.rmse)),
            "mean_nrmse": float(np.mean(self.nrmse)),
            "mean_rel_rms": float(np.mean(self.rel_rms)),
            "n_samples": self.n_samples,
        }


def _safe_div(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.divide(a, b, out=np.full_like(a, np.nan), where=b > 0)


def metrics_from_sums(joints, sse, y_sq, y_range, n) -> TorqueMetrics:
    rmse = np.sqrt(np.asarray(sse) / max(n, 1))
    rms = np.sqrt(np.asarray(y_sq) / max(n, 1))
    return TorqueMetrics(list(joints), rmse, _safe_div(rmse, np.asarray(y_range, float)), _safe_div(rmse, rms), int(n))


def torque_metrics(measured: np.ndarray, predicted: np.ndarray, joints) -> TorqueMetrics:
    """Metrics of predicted vs measured effort, arrays (N, n_joints)."""
    measured = np.asarray(measured, float)
    err = np.asarray(predicted, float) - measured
    rng = measured.max(axis=0) - measured.min(axis=0)
    return metrics_from_sums(joints, (err**2).sum(0), (measured**2).sum(0), rng, measured.shape[0])

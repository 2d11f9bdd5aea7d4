"""Excitation criteria on the base regressor W₁ (samples × rows × base columns):
log cond of the column-equilibrated W₁ and D-optimality −log det(W₁ᵀW₁ / N)."""

from __future__ import annotations

import numpy as np

from ..identification.base import base_parameters

__all__ = ["CRITERIA", "excitation_metrics"]

CRITERIA = ("cond", "dopt")


def _gram(W1: np.ndarray) -> np.ndarray:
    """W₁ᵀW₁ for W₁ of shape (..., N, rows, r) → (..., r, r)."""
    X = np.ascontiguousarray(W1).reshape(-1, W1.shape[-3] * W1.shape[-2], W1.shape[-1])
    M = np.empty((X.shape[0], X.shape[2], X.shape[2]))
    for k in range(X.shape[0]):  # one BLAS gemm each (stacked matmul does not use BLAS)
        M[k] = X[k].T @ X[k]
    return M.reshape(W1.shape[:-3] + M.shape[1:])


def _log_cond(M: np.ndarray, equilibrate: bool = True) -> np.ndarray:
    if equilibrate:
        d = np.sqrt(np.maximum(np.einsum("...ii->...i", M), 1e-300))
        M = M / (d[..., :, None] * d[..., None, :])
    ev = np.linalg.eigvalsh(M)
    lo = np.maximum(ev[..., 0], 1e-300 * np.maximum(ev[..., -1], 1e-300))
    return 0.5 * (np.log(ev[..., -1]) - np.log(lo))


def neg_logdet(M: np.ndarray, n_eq: int) -> np.ndarray:
    sign, logdet = np.linalg.slogdet(M / max(n_eq, 1))
    return np.where(sign > 0, -logdet, np.inf)


def regressor_at(structure, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Regressor at joint-space samples (N, n) in ``structure.robot.joint_names`` order."""
    r = structure.robot
    return structure.evaluate(r.full_configuration(q), r.full_velocity(v), r.full_velocity(a))


def excitation_metrics(structure, q: np.ndarray, v: np.ndarray, a: np.ndarray, independent: np.ndarray | None = None) -> dict:
    """Condition numbers (column-equilibrated and raw) and −log det of the base regressor
    at joint-space samples q, v, v̇ (N, n), in ``structure.robot.joint_names`` order."""
    ind = base_parameters(structure).independent if independent is None else independent
    W1 = regressor_at(structure, q, v, a)[:, :, ind]
    M = _gram(W1)
    n_eq = W1.shape[0] * W1.shape[1]
    return {
        "cond": float(np.exp(_log_cond(M, True))),
        "cond_raw": float(np.exp(_log_cond(M, False))),
        "neg_logdet": float(neg_logdet(M, n_eq)),
        "n_samples": int(W1.shape[0]),
        "n_base": int(W1.shape[2]),
    }

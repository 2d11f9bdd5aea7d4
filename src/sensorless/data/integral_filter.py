"""Stable low-pass filters for acceleration-free dynamics (momentum observer, filtered regressor).

Both the momentum observer (:mod:`sensorless.estimation.momentum`) and the filtered momentum
regressor (:mod:`sensorless.regressor.integral`) apply one stable low-pass L(s) to both sides
of Sᵀτ = ṗ + b and use s L(s) on the momentum p, so that no acceleration is needed.

* :func:`observer_filter`: Tustin (b_p, b_u, a) for the observer's streaming recursion.
* :class:`LowpassChain`: L(s) = (λ/(s + λ))ⁿ as a chain of n first-order lags, discretised
  *exactly* for piecewise-linear inputs (first-order hold, right for sampled smooth signals)
  or piecewise-constant inputs (zero-order hold, right for a torque logged as its mean over
  each sample period), started from zero state at any sample. With x the chain state,

      ẋ = A x + B u,   L[u] = C x,   s L[u] = C A x + C B u,

  and over one period T, for u(t_k + σ) = u_k + (u_{k+1} − u_k) σ/T,

      x_{k+1} = Φ x_k + (F₀ − F₁) u_k + F₁ u_{k+1}      (hold "linear"),
      x_{k+1} = Φ x_k + F₀ ū_k                          (hold "mean", ū_k = mean over [t_k, t_{k+1})),

  with Φ = e^{AT}, F₀ = ∫₀ᵀ e^{Aσ} dσ B, F₁ = (1/T) ∫₀ᵀ e^{A(T−σ)} σ dσ B (one matrix
  exponential of the augmented system, :func:`scipy.linalg.expm`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, signal

from ..errors import RobotModelError

__all__ = ["LowpassChain", "observer_filter"]


def observer_filter(gain: float, order: int, dt: float, damping: float = 1.0):
    """Tustin-discretised (b_p, b_u, a): r = (b_p/a)[p − p₀] − (b_u/a)[τ + β].

    order 1: L(s) = K/(s + K); order 2: L(s) = K²/(s² + 2ζK s + K²), ζ = ``damping``.
    """
    if not (gain > 0 and np.isfinite(gain)):
        raise RobotModelError(f"observer gain must be a positive number [1/s], got {gain}")
    if order == 1:
        den = [1.0, gain]
        num_u = [gain]
    elif order == 2:
        if damping <= 0:
            raise RobotModelError(f"damping must be > 0, got {damping}")
        den = [1.0, 2.0 * damping * gain, gain**2]
        num_u = [gain**2]
    else:
        raise RobotModelError(f"observer order must be 1 or 2, got {order}")
    num_p = list(np.polymul(num_u, [1.0, 0.0]))  # s L(s)
    fs = 1.0 / dt
    b_u, a = signal.bilinear(num_u, den, fs)
    b_p, a2 = signal.bilinear(num_p, den, fs)
    assert np.allclose(a, a2)
    n = len(a)
    pad = lambda b: np.concatenate([np.zeros(n - len(b)), b]) if len(b) < n else np.asarray(b)  # noqa: E731
    return pad(b_p), pad(b_u), np.asarray(a)


@dataclass
class LowpassChain:
    """L(s) = (λ/(s + λ))ⁿ, λ = 2π·``cutoff`` [Hz], sampled every ``dt`` s (see the module docstring)."""

    cutoff: float
    order: int
    dt: float
    A: np.ndarray = field(init=False, repr=False)
    lam: float = field(init=False, repr=False)
    Phi: np.ndarray = field(init=False, repr=False)
    F0: np.ndarray = field(init=False, repr=False)
    F1: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if not (self.cutoff > 0 and np.isfinite(self.cutoff)):
            raise RobotModelError(f"filter cut-off must be a positive frequency [Hz], got {self.cutoff}")
        if self.order not in (1, 2, 3):
            raise RobotModelError(f"filter order must be 1, 2 or 3, got {self.order}")
        if not self.dt > 0:
            raise RobotModelError(f"sample period must be > 0, got {self.dt}")
        n, lam, T = self.order, 2 * np.pi * self.cutoff, self.dt
        self.A = lam * (np.eye(n, k=-1) - np.eye(n))
        self.lam = lam
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = self.A * T
        M[0, n] = lam * T  # B = λ e₁
        M[n, n + 1] = T
        E = linalg.expm(M)
        self.Phi, self.F0, self.F1 = E[:n, :n], E[:n, n], E[:n, n + 1] / T

    def states(self, u: np.ndarray, hold: str = "linear") -> np.ndarray:
        """Chain states (N, n, *u.shape[1:]) for the input samples ``u`` (N, ...), x₀ = 0."""
        if hold not in ("linear", "mean"):
            raise RobotModelError(f"hold must be 'linear' or 'mean', got {hold!r}")
        u = np.asarray(u, dtype=float)
        N = u.shape[0]
        flat = u.reshape(N, -1)
        x = np.zeros((N, self.order, flat.shape[1]))
        if hold == "linear":
            w = np.einsum("i,nj->nij", self.F0 - self.F1, flat[:-1]) + np.einsum("i,nj->nij", self.F1, flat[1:])
        else:
            w = np.einsum("i,nj->nij", self.F0, flat[:-1])
        Phi = self.Phi
        for k in range(N - 1):
            x[k + 1] = Phi @ x[k] + w[k]
        return x.reshape((N, self.order) + u.shape[1:])

    def value(self, x: np.ndarray) -> np.ndarray:
        """L[u] = C x (the chain's last state)."""
        return x[:, -1]

    def rate(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """s L[u] = C A x + C B u (C B = λ for order 1, else 0)."""
        out = np.tensordot(self.A[-1], x, axes=([0], [1]))
        return out + self.lam * u if self.order == 1 else out

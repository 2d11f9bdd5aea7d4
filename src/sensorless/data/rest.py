"""Rest detection: a joint at rest gets v = v̇ = 0 (no sliding friction, no noise chatter).

A robot at rest logs v = noise n. Sliding friction fs sgn(n) (or fs tanh(n/ε)) would then
chatter by up to fs, far above the torque noise of a geared arm, while any smoothing wide
enough to hide it blurs the friction in motion. Per sample, rest and a slow motion lost in
the noise cannot be told apart; over time they can: at rest |v| stays within the noise.

Joint j is **at rest** at sample k when, over the centred window of ``window`` samples
(default: the derivative window, 0.2 s),

* |v_j| ≤ δ_j = ``REST_SIGMAS`` · σ_v,j at every sample (5: a Gaussian noise exceeds it once
  in ~2·10⁶ samples; a velocity reversal is not rest, |v| exceeds δ near it), and
* q_j moves less than ``RANGE_SIGMAS`` · σ_q,j (max − min over the window; 8: the range of
  ≤ 41 Gaussian samples is 4–5 σ on average): a joint creeping below the velocity noise,
  common where v is a quantised encoder difference, still moves.

There v_j and v̇_j are set to 0.

σ_j is the white-noise std of the logged v (:func:`signal_noise`), measured before any
low-pass (a filter colours the noise and its edge transients, often on a rest at the start
of a log, give the filtered noise heavier tails than its white-noise gain predicts).
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError

__all__ = ["RANGE_SIGMAS", "REST_SIGMAS", "REST_MODES", "rest_mask", "signal_noise", "zero_at_rest"]

REST_SIGMAS = 5.0
RANGE_SIGMAS = 8.0
REST_MODES = ("auto", "off")


def signal_noise(x: np.ndarray, window: int = 11, polyorder: int = 3) -> np.ndarray:
    """Per-column white-noise std of ``x`` (N, n) from its Savitzky–Golay residual r = x − S x:
    var r = σ² (1 − c₀), c₀ the smoother's centre coefficient, so σ̂ = 1.4826 MAD(r) / √(1 − c₀)
    (robust to the motion's own residual at reversals)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.shape[0] < window + 2:
        raise DataError(f"{x.shape[0]} samples are too few to estimate the noise (need > {window + 2})")
    from scipy.signal import savgol_coeffs, savgol_filter  # imported on use (CLI start-up)

    r = x - savgol_filter(x, window, polyorder, axis=0, mode="interp")
    c0 = savgol_coeffs(window, polyorder)[window // 2]
    r = r[window:-window] if x.shape[0] > 3 * window else r
    mad = np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(1.0 - c0)


def rest_mask(v: np.ndarray, sigma: np.ndarray, window: int, sigmas: float = REST_SIGMAS,
              q: "np.ndarray | None" = None, sigma_q: "np.ndarray | None" = None) -> np.ndarray:
    """(N, n) bool: |v| ≤ sigmas · σ throughout the centred window and, with ``q``, a position
    range within ``RANGE_SIGMAS`` · σ_q over it (module docstring)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d  # imported on use (CLI start-up)

    w = max(int(window), 1)
    peak = maximum_filter1d(np.abs(np.asarray(v, dtype=float)), size=w, axis=0, mode="nearest")
    mask = peak <= sigmas * np.asarray(sigma, dtype=float)[None, :]
    if q is not None and sigma_q is not None:
        q = np.asarray(q, dtype=float)
        span = maximum_filter1d(q, size=w, axis=0, mode="nearest") - minimum_filter1d(q, size=w, axis=0, mode="nearest")
        mask &= span <= RANGE_SIGMAS * np.asarray(sigma_q, dtype=float)[None, :]
    return mask


def zero_at_rest(traj, sigma: np.ndarray, window: int, sigma_q: "np.ndarray | None" = None):
    """``traj`` with v = v̇ = 0 where a joint is at rest; provenance["rest"] records σ, δ and
    the fraction of samples at rest per joint."""
    mask = rest_mask(traj.v, sigma, window, q=None if sigma_q is None else traj.q, sigma_q=sigma_q)
    v = np.where(mask, 0.0, traj.v)
    a = None if traj.a is None else np.where(mask, 0.0, traj.a)
    info = {"velocity_noise": dict(zip(traj.joint_names, map(float, sigma))),
            "rest_velocity": dict(zip(traj.joint_names, map(float, REST_SIGMAS * np.asarray(sigma)))),
            "window_samples": int(window),
            "position_noise": None if sigma_q is None else dict(zip(traj.joint_names, map(float, sigma_q))),
            "fraction_at_rest": dict(zip(traj.joint_names, map(float, mask.mean(axis=0))))}
    return traj.with_(v=v, a=a, provenance={**traj.provenance, "rest": info})

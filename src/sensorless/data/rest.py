"""Rest detection: a joint at rest gets v = v̇ = 0 (no sliding friction, no noise chatter); a
joint creeping slower than the velocity noise keeps sliding, at its measured drift.

A robot at rest logs v = noise n. Sliding friction fs sgn(n) (or fs tanh(n/ε)) would then
chatter by up to fs, far above the torque noise of a geared arm, while any smoothing wide
enough to hide it blurs the friction in motion. Per sample, rest and a slow motion lost in
the noise cannot be told apart; over time they can: at rest |v| stays within the noise and q
does not drift.

Joint j is **quiet** at sample k when, over the centred window of ``window`` samples
(default: the derivative window, 0.2 s),

* |v_j| ≤ δ_j = ``REST_SIGMAS`` · σ_v,j at every sample (5: a Gaussian noise exceeds it once
  in ~2·10⁶ samples; a velocity reversal is not rest, |v| exceeds δ near it), and
* q_j moves less than ``RANGE_SIGMAS`` · σ_q,j (max − min over the window; 8: the range of
  ≤ 41 Gaussian samples is 4–5 σ on average).

A quiet joint is **creeping** (sliding under a load its friction barely holds, e.g. a joint
sagging at 3·10⁻⁴ rad/s with a torque equal to its Coulomb friction) when it drifts consistently
in one direction. With q_i = q̄ + c t_i + e_i and v_i = c + n_i (white noise of std σ_q, σ_v),
the drift c over the ``creep_window`` samples around k (``CREEP_SECONDS``, cut at the ends of the
quiet stretch, so a motion next to it does not leak in) is estimated by

    the mean velocity   v̄ = Σ v_i / n,                   SE = σ_v / √n,
    the position slope  ŝ = Σ (t_i − t̄)(q_i − q̄) / Σ (t_i − t̄)²,   SE = σ_q / √Σ (t_i − t̄)²,

whichever has the smaller standard error (v is often a difference of q, so the two are not
independent and are not pooled). The joint creeps where |ĉ| > ``CREEP_SIGMAS`` · SE (5: a joint at
rest passes for creeping about once in 2·10⁶ windows). Every σ here is floored at the signal's
quantization noise Δ/√12, Δ its step or rounding read from the log (:mod:`~sensorless.data.resolution`),
so that a quantised encoder or a q and v logged to 4 decimals at rest do not have zero noise (δ ≥
1.4 Δ: one quantum of v is quiet).

A quiet joint that is not creeping is **at rest**: v_j = v̇_j = 0 there. A creeping joint gets
v_j = ĉ (the sign of its friction is known, its speed far better than from one noisy sample)
and v̇_j = 0 (steady sliding).

σ_j is the white-noise std of the logged v and q (:func:`signal_noise`), measured before any
low-pass (a filter colours the noise and its edge transients, often on a rest at the start
of a log, give the filtered noise heavier tails than its white-noise gain predicts).
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError
from .resolution import noise_floor
from .savgol import savgol_coeffs, savgol_filter

__all__ = ["CREEP_SECONDS", "CREEP_SIGMAS", "NOISE_SAMPLES", "RANGE_SIGMAS", "REST_SIGMAS", "REST_MODES", "creep_drift", "rest_info", "rest_mask", "rest_state",
           "signal_noise", "zero_at_rest"]

REST_SIGMAS = 5.0
RANGE_SIGMAS = 8.0
CREEP_SIGMAS = 5.0
#: length of the window over which a quiet joint's drift is measured [s]
CREEP_SECONDS = 1.0
REST_MODES = ("auto", "off")


#: at most about this many residuals enter :func:`signal_noise`'s MAD (every k-th of a longer log): its
#: relative standard error is then ~0.3 %, and a 10⁶-sample log's scan spends ~5 ms per column on the
#: two medians instead of ~27 ms
NOISE_SAMPLES = 200_000


def signal_noise(x: np.ndarray, window: int = 11, polyorder: int = 3) -> np.ndarray:
    """Per-column white-noise std of ``x`` (N, n) from its Savitzky–Golay residual r = x − S x:
    var r = σ² (1 − c₀), c₀ the smoother's centre coefficient, so σ̂ = 1.4826 MAD(r) / √(1 − c₀)
    (robust to the motion's own residual at reversals); the MAD of every k-th residual beyond
    :data:`NOISE_SAMPLES`. Never below the column's quantization noise Δ/√12
    (:func:`~sensorless.data.resolution.noise_floor`: a rounded signal held still has a MAD of 0)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.shape[0] < window + 2:
        raise DataError(f"{x.shape[0]} samples are too few to estimate the noise (need > {window + 2})")
    r = x - savgol_filter(x, window, polyorder, axis=0, mode="interp")
    c0 = savgol_coeffs(window, polyorder)[window // 2]
    r = r[window:-window] if x.shape[0] > 3 * window else r
    r = r[:: -(-len(r) // NOISE_SAMPLES)]
    mad = np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    return np.maximum(1.4826 * mad / np.sqrt(1.0 - c0), noise_floor(x))


def _quiet(v, sigma, window, sigmas, q, sigma_q) -> np.ndarray:
    from .window_filters import running_max, running_min

    w = max(int(window), 1)
    peak = running_max(np.abs(v), w)
    mask = peak <= sigmas * _quantum_floor(v, sigma)[None, :]
    if q is not None and sigma_q is not None:
        span = running_max(q, w) - running_min(q, w)
        mask &= span <= RANGE_SIGMAS * _quantum_floor(q, sigma_q)[None, :]
    return mask


def _quantum_floor(x: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """σ floored at the column's quantization noise Δ/√12 (:func:`~sensorless.data.resolution.noise_floor`)."""
    return np.maximum(np.asarray(sigma, dtype=float), noise_floor(x))


def _window_sums(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    c = np.concatenate([[0.0], np.cumsum(x)])
    return c[hi] - c[lo]


def creep_drift(v: np.ndarray, q: np.ndarray, sigma_v: np.ndarray, sigma_q: np.ndarray, quiet: np.ndarray,
                dt: float, creep_window: int) -> tuple[np.ndarray, np.ndarray]:
    """(creeping, drift), each (N, n): where a quiet joint drifts significantly, and its drift
    velocity ĉ (module docstring; 0 elsewhere). ``quiet``: the quiet samples (:func:`rest_mask`
    without the drift test); windows of ``creep_window`` samples are cut at its stretches' ends."""
    v, q = np.asarray(v, dtype=float), np.asarray(q, dtype=float)
    creeping = np.zeros(v.shape, dtype=bool)
    drift = np.zeros(v.shape)
    sv, sq = _quantum_floor(v, sigma_v), _quantum_floor(q, sigma_q)
    h = max(int(creep_window), 3) // 2
    for j in range(v.shape[1]):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], quiet[:, j].astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):  # one quiet stretch [a, b)
            k = np.arange(b - a)
            lo, hi = np.maximum(k - h, 0), np.minimum(k + h + 1, b - a)
            n = (hi - lo).astype(float)
            t = k.astype(float)
            qq = q[a:b, j] - q[a, j]
            st, stt = _window_sums(t, lo, hi), _window_sums(t * t, lo, hi)
            sxx = np.maximum(stt - st**2 / n, 0.0)  # Σ (t − t̄)² [samples²]
            slope = (_window_sums(t * qq, lo, hi) - st * _window_sums(qq, lo, hi) / n) / np.where(sxx > 0, sxx, 1.0) / dt
            se_s = np.where(sxx > 0, sq[j] / np.sqrt(np.where(sxx > 0, sxx, 1.0)) / dt, np.inf)
            mean = _window_sums(v[a:b, j], lo, hi) / n
            se_v = sv[j] / np.sqrt(n)
            est, se = np.where(se_v <= se_s, mean, slope), np.minimum(se_v, se_s)
            sig = (n >= 3) & (np.abs(est) > CREEP_SIGMAS * se)
            creeping[a:b, j] = sig
            drift[a:b, j] = np.where(sig, est, 0.0)
    return creeping, drift


def rest_mask(v: np.ndarray, sigma: np.ndarray, window: int, sigmas: float = REST_SIGMAS,
              q: "np.ndarray | None" = None, sigma_q: "np.ndarray | None" = None, dt: "float | None" = None,
              creep_window: "int | None" = None) -> np.ndarray:
    """(N, n) bool: at rest (module docstring): |v| ≤ sigmas · σ throughout the centred window and,
    with ``q``, a position range within ``RANGE_SIGMAS`` · σ_q over it and, with ``q`` and ``dt``
    [s], no significant drift over ``creep_window`` samples (default ``CREEP_SECONDS``)."""
    v = np.asarray(v, dtype=float)
    q = None if q is None else np.asarray(q, dtype=float)
    mask = _quiet(v, sigma, window, sigmas, q, sigma_q)
    if q is None or sigma_q is None or dt is None:
        return mask
    cw = creep_window if creep_window is not None else max(int(window), int(round(CREEP_SECONDS / dt)))
    creeping, _ = creep_drift(v, q, sigma, sigma_q, mask, dt, cw)
    return mask & ~creeping


def rest_state(v: np.ndarray, dt: float, sigma: np.ndarray, window: int, q: "np.ndarray | None" = None,
               sigma_q: "np.ndarray | None" = None) -> "tuple[np.ndarray, np.ndarray, np.ndarray]":
    """``(quiet, creeping, v_new)`` of :func:`zero_at_rest` for velocities ``v (N, n)`` sampled every
    ``dt`` s: the quiet mask (v̇ = 0 there), the creeping mask (quiet, with the drift as velocity) and the
    velocity with 0 at rest and the drift where creeping. The streamed scan calls it one joint at a time,
    without a Trajectory around the arrays (memory)."""
    quiet = _quiet(v, sigma, window, REST_SIGMAS, q, sigma_q)
    creeping, drift = np.zeros_like(quiet), None
    if q is not None and dt > 0:
        cw = max(int(window), int(round(CREEP_SECONDS / dt)))
        creeping, drift = creep_drift(v, q, sigma, sigma_q, quiet, dt, cw)
    v_new = np.where(quiet & ~creeping, 0.0, v)
    if drift is not None:
        np.copyto(v_new, drift, where=creeping)
    return quiet, creeping, v_new


def zero_at_rest(traj, sigma: np.ndarray, window: int, sigma_q: "np.ndarray | None" = None):
    """``traj`` with v = v̇ = 0 where a joint is at rest, and v = its drift, v̇ = 0 where it creeps
    (module docstring, :func:`rest_state`); provenance["rest"] records σ, δ and the fractions of samples
    at rest and creeping per joint."""
    v = np.asarray(traj.v, dtype=float)
    q = None if sigma_q is None else np.asarray(traj.q, dtype=float)
    dt = float(np.median(np.diff(traj.t))) if len(traj.t) > 1 else 0.0
    quiet, creeping, v = rest_state(v, dt, sigma, window, q, sigma_q)
    a = None if traj.a is None else np.where(quiet, 0.0, traj.a)
    info = rest_info(traj.joint_names, sigma, window, sigma_q, (quiet & ~creeping).mean(axis=0), creeping.mean(axis=0))
    return traj.with_(v=v, a=a, provenance={**traj.provenance, "rest": info})


def rest_info(names, sigma: np.ndarray, window: int, sigma_q: "np.ndarray | None", fraction_at_rest: np.ndarray,
              fraction_creeping: np.ndarray) -> dict:
    """The ``provenance["rest"]`` record of :func:`zero_at_rest` (and of the streamed scan)."""
    return {"velocity_noise": dict(zip(names, map(float, sigma))),
            "rest_velocity": dict(zip(names, map(float, REST_SIGMAS * np.asarray(sigma)))),
            "window_samples": int(window),
            "position_noise": None if sigma_q is None else dict(zip(names, map(float, sigma_q))),
            "fraction_at_rest": dict(zip(names, map(float, fraction_at_rest))),
            "fraction_creeping": dict(zip(names, map(float, fraction_creeping)))}

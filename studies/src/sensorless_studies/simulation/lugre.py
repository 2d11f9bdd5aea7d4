"""A single joint on a friction test bench with LuGre friction: presliding and hysteresis.

Ground truth for the friction state (:mod:`sensorless.regressor.friction_state`). LuGre
(Canudas de Wit et al. 1995) with bristle deflection z [rad]:

    ż = v − σ0 |v| z / g(v),   g(v) = fc + (fs − fc) exp(−(v/vs)²),
    τ_f = σ0 z + σ1 ż + σ2 v,   τ = J v̇ + τ_f + o.

Near a reversal the friction torque ramps over a displacement of about fc/σ0 while the joint
barely moves (presliding), and the lag of z behind its steady state g(v) sgn(v)/σ0 gives
hysteresis in the friction–velocity plane. ``sigma0=None`` is the static limit (σ0 → ∞):
τ_f = g(v) sgn v + σ2 v, a joint *without* the effect.

The bench prescribes a smooth velocity (:func:`velocity_profile`: random knots with cosine
transitions, many reversals, slow segments and rests); q and v̇ follow analytically, and z is
integrated with SciPy's ``solve_ivp`` (LSODA: the bristle dynamics is stiff at speed). Samples are
taken at jittered instants (irregular steps), with white noise on q, v and τ.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from sensorless.data.trajectory import Trajectory

__all__ = ["LuGreJoint", "VelocityProfile", "lugre_friction", "simulate_lugre_joint", "velocity_profile",
           "write_bench_csv"]


@dataclasses.dataclass(frozen=True)
class LuGreJoint:
    """LuGre parameters [N·m, rad/s, N·m/rad, N·m·s/rad, kg·m²]; ``sigma0=None``: static limit."""

    fc: float = 0.3
    fs: float = 0.45
    vs: float = 0.02
    sigma0: "float | None" = 150.0
    sigma1: float = 0.5
    sigma2: float = 0.05
    inertia: float = 0.01
    offset: float = 0.0

    def g(self, v: np.ndarray) -> np.ndarray:
        return self.fc + (self.fs - self.fc) * np.exp(-((np.asarray(v) / self.vs) ** 2))


@dataclasses.dataclass(frozen=True)
class VelocityProfile:
    """Piecewise velocity: value ``v[k]`` at knot ``t[k]``, cosine transition to the next knot."""

    t: np.ndarray
    v: np.ndarray

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q − q(0), v, v̇) at times ``t`` (exact: the cosine blend is integrated in closed form)."""
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        t0, dt = self.t[k], np.diff(self.t)[k]
        v0, dv = self.v[k], np.diff(self.v)[k]
        u = np.clip((t - t0) / dt, 0.0, 1.0)
        v = v0 + dv * (1 - np.cos(np.pi * u)) / 2
        a = dv * np.pi * np.sin(np.pi * u) / (2 * dt)
        seg = np.diff(self.t) * (self.v[:-1] + np.diff(self.v) / 2)  # displacement over each full segment
        q_knot = np.concatenate([[0.0], np.cumsum(seg)])
        q = q_knot[k] + dt * (v0 * u + dv * (u - np.sin(np.pi * u) / np.pi) / 2)
        return q, v, a


def velocity_profile(duration: float, seed: int = 0, *, v_max: float = 0.5, v_slow: float = 0.005,
                     reversal_prob: float = 0.7, rest_prob: float = 0.2) -> VelocityProfile:
    """Random bench profile: plateaus of |v| log-uniform in [``v_slow``, ``v_max``] held 0.5–3 s, sign
    flipped with probability ``reversal_prob`` (cosine transitions of 0.5–3 s: slow reversals), and a
    rest (v = 0 for 0.3–1.5 s) before a plateau with probability ``rest_prob``."""
    rng = np.random.default_rng(seed)
    t, v, now, sign = [0.0], [0.0], 0.0, 1.0
    while now < duration:
        if rng.random() < rest_prob:
            now += rng.uniform(0.3, 1.5)
            t.append(now)
            v.append(0.0)
        sign = -sign if rng.random() < reversal_prob else sign
        mag = float(np.exp(rng.uniform(np.log(v_slow), np.log(v_max))))
        now += rng.uniform(0.5, 3.0)  # transition
        t.append(now)
        v.append(sign * mag)
        now += rng.uniform(0.5, 3.0)  # hold
        t.append(now)
        v.append(sign * mag)
    t.append(now + 1.0)
    v.append(0.0)
    return VelocityProfile(np.array(t), np.array(v))


def lugre_friction(truth: LuGreJoint, profile: VelocityProfile, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(τ_f, z) of ``truth`` along ``profile`` at times ``t`` (z(0) = 0; ``solve_ivp`` LSODA, tight tolerances)."""
    from scipy.integrate import solve_ivp

    t = np.asarray(t, dtype=float)
    v = profile(t)[1]
    if truth.sigma0 is None:
        return truth.g(v) * np.sign(v) + truth.sigma2 * v, np.zeros_like(t)
    s0 = float(truth.sigma0)

    def rhs(time, z):
        vt = profile(np.array([time]))[1][0]
        return [vt - s0 * abs(vt) * z[0] / truth.g(vt)]

    sol = solve_ivp(rhs, (float(t[0]), float(t[-1])), [0.0], method="LSODA", t_eval=t, rtol=1e-9, atol=1e-12,
                    max_step=0.05)
    if not sol.success:  # pragma: no cover - LSODA on a scalar smooth ODE
        raise RuntimeError(f"LuGre integration failed: {sol.message}")
    z = sol.y[0]
    zdot = v - s0 * np.abs(v) * z / truth.g(v)
    return s0 * z + truth.sigma1 * zdot + truth.sigma2 * v, z


def simulate_lugre_joint(truth: LuGreJoint = LuGreJoint(), *, duration: float = 60.0, rate: float = 200.0,
                         seed: int = 0, jitter: float = 0.3, noise_q: float = 1e-5, noise_v: float = 2e-4,
                         noise_tau: float = 0.005, joint: str = "joint", profile: "VelocityProfile | None" = None,
                         **profile_options) -> tuple[Trajectory, np.ndarray]:
    """A bench log of ``truth`` (module docstring): ``(Trajectory with t, q, v, v̇, τ; true τ_f)``.
    Steps are 1/``rate`` × U(1 − ``jitter``, 1 + ``jitter``); the noise stds are in SI units."""
    rng = np.random.default_rng(seed + 1)
    profile = profile if profile is not None else velocity_profile(duration, seed, **profile_options)
    n = int(duration * rate)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(1 - jitter, 1 + jitter, n - 1) / rate)])
    q, v, a = profile(t)
    tau_f, _ = lugre_friction(truth, profile, t)
    tau = truth.inertia * a + tau_f + truth.offset
    traj = Trajectory(t=t, q=(q + rng.normal(0, noise_q, n))[:, None], v=(v + rng.normal(0, noise_v, n))[:, None],
                      a=a[:, None], tau=(tau + rng.normal(0, noise_tau, n))[:, None], joint_names=(joint,),
                      source=f"<lugre seed {seed}>")
    return traj, tau_f


def write_bench_csv(traj: Trajectory, path: "str | Path", *, velocity: bool = True) -> Path:
    """A single-joint bench CSV with columns ``t, q[, v], tau`` (what ``sensorless friction`` reads)."""
    import pandas as pd

    cols = {"t": traj.t, "q": traj.q[:, 0]}
    if velocity and traj.v is not None:
        cols["v"] = traj.v[:, 0]
    cols["tau"] = traj.tau[:, 0]
    path = Path(path)
    pd.DataFrame(cols).to_csv(path, index=False, float_format="%.9g")
    return path

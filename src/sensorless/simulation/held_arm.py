"""A position-controlled arm with stiction, held still (or tracking) and pushed by hand.

The true robot (a :class:`~.synthetic.TruthModel`: inertials, armature, viscous friction fv,
an offset o) has per-joint dry friction with a static level above the Coulomb one
(:class:`Stiction`: f_s > f_c). A joint position loop of the *nominal* model,

    τ = g_nom(q) + Kp (q_ref − q) − Kd v          (q_ref fixed: held still; or a Fourier reference),

drives it; pushes are forces at a frame (:class:`~.arm_push.Push`). Forward dynamics with the
Karnopp stick–slip law, joint by joint:

    M(q) v̇ = τ + J(q)ᵀ[F; 0] − h(q, v) − fv v − o − f,
    sliding (|v| > v_stick):  f = sgn v · (f_c + (f_s − f_c) exp(−(v/v_s)²)),
    stuck (the set S):        v̇_S = −v_S / dt and f_S = whatever holds it, if |f_S| ≤ f_s.

S starts as the joints slower than ``v_stick`` plus those whose velocity would change sign in
the step; f_S comes from the partitioned equations (M_FF a_F = u_F − f_F − M_FS a_S,
f_S = u_S − M_SF a_F − M_SS a_S), and the joint whose |f_S| exceeds f_s most is released
with f = f_s sgn f_S (breakaway) until the set is consistent. A joint that stops therefore
keeps whatever holding torque its position loop had when it stuck: after a push the logged
torque settles at a new level anywhere in the static band (the case a collision monitor
must not take for a contact). Semi-implicit Euler at ``sim_rate``, τ held over a step; the
log (every ``sim_rate / log_rate`` steps) holds q, v and the motor torque τ with white
noise (a current times its torque constant), stamped from ``t0`` (e.g. Unix time). The
truth returned beside it is :class:`~.arm_push.PushTruth` (τ_ext = Jᵀ F, F, on/off).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import SensorlessError
from ..excitation import random_fourier
from ..robot import Robot
from .arm_push import Push, PushTruth
from .synthetic import NoiseSpec, TruthModel, add_white_noise

__all__ = ["Stiction", "karnopp_step", "simulate_held_arm"]


@dataclass(frozen=True)
class Stiction:
    """Per-joint dry friction: Coulomb ``fc``, static ``fs`` (≥ fc) [N·m], Stribeck velocity ``vs`` [rad/s]."""

    fc: np.ndarray
    fs: np.ndarray
    vs: float | np.ndarray = 0.05

    def __post_init__(self) -> None:
        fc, fs = np.asarray(self.fc, float), np.asarray(self.fs, float)
        if fc.shape != fs.shape or np.any(fc < 0) or np.any(fs < fc):
            raise SensorlessError(f"stiction needs 0 ≤ fc ≤ fs per joint, got fc={fc}, fs={fs}")

    def sliding(self, v: np.ndarray) -> np.ndarray:
        """Dry friction of sliding joints: sgn v (fc + (fs − fc) exp(−(v/vs)²))."""
        return np.sign(v) * (self.fc + (self.fs - self.fc) * np.exp(-((v / self.vs) ** 2)))


def karnopp_step(M: np.ndarray, u: np.ndarray, v: np.ndarray, dt: float, st: Stiction,
                 v_stick: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """(v̇, f): accelerations and dry friction of one step of M v̇ = u − f (module docstring)."""
    n = len(v)
    fs = np.asarray(st.fs, float)
    stuck = np.abs(v) < v_stick
    f = st.sliding(v)
    a = np.linalg.solve(M, u - f)
    stuck |= (v * (v + dt * a) < 0) & (fs > 0)  # a sliding joint would reverse within the step: let it stop
    breakaway = np.zeros(n, bool)
    for _ in range(n + 1):
        S, F = np.flatnonzero(stuck), np.flatnonzero(~stuck)
        f = np.where(breakaway, f, st.sliding(v))
        a = np.zeros(n)
        a[S] = -v[S] / dt
        if F.size:
            a[F] = np.linalg.solve(M[np.ix_(F, F)], u[F] - f[F] - M[np.ix_(F, S)] @ a[S])
        f[S] = u[S] - M[S] @ a
        excess = np.abs(f[S]) - fs[S]
        if not S.size or excess.max() <= 0:
            return a, f
        j = S[int(np.argmax(excess / np.maximum(fs[S], 1e-12)))]
        stuck[j], breakaway[j] = False, True
        f[j] = fs[j] * np.sign(f[j])
    raise SensorlessError("stick–slip solve did not settle")  # pragma: no cover - n + 1 releases at most


def simulate_held_arm(
    truth: TruthModel,
    nominal: Robot,
    stiction: Stiction,
    pushes: Sequence[Push] = (),
    *,
    hold: np.ndarray | None = None,
    duration: float = 60.0,
    sim_rate: float = 1000.0,
    log_rate: float = 500.0,
    settle: float = 1.0,
    t0: float = 0.0,
    seed: int = 0,
    noise: NoiseSpec | None = None,
    kp: float | np.ndarray = 400.0,
    kd: float | np.ndarray = 20.0,
    base_freq: float = 0.1,
    max_velocity: float = 1.0,
) -> tuple[Trajectory, PushTruth]:
    """Simulate; return (log, truth). ``hold``: the held joint positions (None: track a random
    Fourier reference of ``base_freq``, ``max_velocity``). The arm first settles for ``settle``
    s (not logged); push times are seconds after the first logged sample."""
    ratio = sim_rate / log_rate
    if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
        raise SensorlessError(f"sim_rate ({sim_rate}) must be an integer multiple of log_rate ({log_rate})")
    r = truth.robot
    if r.floating_base or r.n_actuated != r.nv:
        raise SensorlessError(f"{r.name}: the held-arm simulation needs a fixed-base, fully actuated arm")
    model = r.model.copy()
    model.armature[:] = truth.armature
    data = model.createData()
    nom_model = nominal.model
    nom_data = nom_model.createData()
    fids = {p.frame: r.frame_id(p.frame) for p in pushes}
    dt = 1.0 / sim_rate
    n_settle, n_steps, decim = int(round(settle * sim_rate)), int(round(duration * sim_rate)), int(round(ratio))
    t_all = (np.arange(n_settle + n_steps + 1) - n_settle) * dt
    if hold is None:
        ref = random_fourier(r, rng=seed, base_freq=base_freq, max_velocity=max_velocity, max_acceleration=3.0)
        Qr, Vr, _ = ref.evaluate(np.maximum(t_all, 0.0))
        Vr[t_all < 0] = 0.0
    else:
        Qr = np.tile(np.asarray(hold, float), (len(t_all), 1))
        Vr = np.zeros_like(Qr)
    q, v = Qr[0].copy(), np.zeros(r.nv)
    logs = {k: [] for k in ("t", "q", "v", "tau", "ext", "F", "on")}
    for k, t in enumerate(t_all):
        tau = pin.computeGeneralizedGravity(nom_model, nom_data, q) + kp * (Qr[k] - q) + kd * (Vr[k] - v)
        ext, F_tot, on = np.zeros(r.nv), np.zeros(3), False
        for p in pushes:
            F = p.force(t)
            if np.any(F):
                on = True
                J = pin.computeFrameJacobian(model, data, q, fids[p.frame], pin.LOCAL_WORLD_ALIGNED)
                ext += J[:3].T @ F
                F_tot += F
        if k >= n_settle and (k - n_settle) % decim == 0:
            for key, val in zip(logs, (t, q, v, tau, ext, F_tot, on)):
                logs[key].append(np.copy(val))
        if k == len(t_all) - 1:
            break
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        u = tau + ext - pin.nonLinearEffects(model, data, q, v) - truth.fv * v - truth.offset
        a, _ = karnopp_step(M, u, v, dt, stiction)
        v = v + dt * a
        q = pin.integrate(model, q, dt * v)
    rng = np.random.default_rng(seed + 1)
    arr = {k: np.array(v_) for k, v_ in logs.items()}
    noise = NoiseSpec.none() if noise is None else noise
    traj = Trajectory(
        t=t0 + arr["t"], q=add_white_noise(arr["q"], noise.q, rng), v=add_white_noise(arr["v"], noise.v, rng),
        tau=add_white_noise(arr["tau"], noise.tau, rng), joint_names=r.joint_names,
        source=f"<held {r.name} seed={seed}>", units={"t": "s", "q": "rad", "v": "rad/s", "tau": "N·m"},
    )
    return traj, PushTruth(arr["t"], arr["ext"], arr["F"], arr["on"].astype(bool), tuple(pushes), 0.0)

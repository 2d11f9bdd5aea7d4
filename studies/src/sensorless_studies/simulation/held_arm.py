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

from sensorless.data.trajectory import Trajectory
from sensorless.errors import SensorlessError
from sensorless.excitation import random_fourier
from sensorless.robot import Robot
from .arm_push import Push, PushTruth, log_decimation, noisy_joint_log, push_torques
from sensorless.testing import NoiseSpec, TruthModel, add_white_noise

__all__ = ["HeldArmScenario", "Stiction", "held_arm_scenario", "karnopp_step", "noise_implied_force", "simulate_held_arm"]


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
    if stuck.all():  # the held arm's common case: does static friction hold every joint?
        a = -v / dt
        f = u - M @ a
        if np.all(np.abs(f) <= fs):
            return a, f
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
    reference=None,
    duration: float = 60.0,
    sim_rate: float = 500.0,
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
    """Simulate; return (log, truth). ``hold``: the held joint positions; ``reference``: an object
    whose ``evaluate(t)`` gives (q, v, v̇) references; neither: a random Fourier reference of
    ``base_freq``, ``max_velocity``. The arm first settles for ``settle``
    s (not logged); push times are seconds after the first logged sample."""
    decim = log_decimation(sim_rate, log_rate)
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
    n_settle, n_steps = int(round(settle * sim_rate)), int(round(duration * sim_rate))
    t_all = (np.arange(n_settle + n_steps + 1) - n_settle) * dt
    if reference is not None:
        Qr, Vr, _ = reference.evaluate(np.maximum(t_all, 0.0))
        Vr[t_all < 0] = 0.0
    elif hold is None:
        ref = random_fourier(r, rng=seed, base_freq=base_freq, max_velocity=max_velocity, max_acceleration=3.0)
        Qr, Vr, _ = ref.evaluate(np.maximum(t_all, 0.0))
        Vr[t_all < 0] = 0.0
    else:
        Qr = np.tile(np.asarray(hold, float), (len(t_all), 1))
        Vr = np.zeros_like(Qr)
    q, v = Qr[0].copy(), np.zeros(r.nv)
    lower = np.tril_indices(r.nv, -1)
    logs = {k: [] for k in ("t", "q", "v", "tau", "ext", "F", "on")}
    for k, t in enumerate(t_all):
        tau = pin.computeGeneralizedGravity(nom_model, nom_data, q) + kp * (Qr[k] - q) + kd * (Vr[k] - v)
        ext, F_tot, on = push_torques(model, data, q, pushes, fids, t)
        if k >= n_settle and (k - n_settle) % decim == 0:
            for key, val in zip(logs, (t, q, v, tau, ext, F_tot, on)):
                logs[key].append(np.copy(val))
        if k == len(t_all) - 1:
            break
        M = pin.crba(model, data, q).copy()
        M[lower] = M.T[lower]
        u = tau + ext - pin.nonLinearEffects(model, data, q, v) - truth.fv * v - truth.offset
        a, _ = karnopp_step(M, u, v, dt, stiction)
        v = v + dt * a
        q = pin.integrate(model, q, dt * v)
    arr = {k: np.array(v_) for k, v_ in logs.items()}
    traj = noisy_joint_log(arr, r, noise, seed, f"<held {r.name} seed={seed}>", t0)
    return traj, PushTruth(arr["t"], arr["ext"], arr["F"], arr["on"].astype(bool), tuple(pushes), 0.0)


@dataclass
class HeldArmScenario:
    """One simulated held-still arm: a training log (tracking a Fourier reference), the held log
    pushed by hand, the truth, and the figures the monitor is scored against."""

    robot: str
    train: Trajectory
    log: Trajectory
    truth: PushTruth
    still: np.ndarray  # (N,) every joint stuck for ≥ 0.5 s and no push on
    hold: np.ndarray
    stiction: Stiction
    noise: NoiseSpec
    noise_force: float  # noise-implied force at the hold pose [N] (:func:`noise_implied_force`)


def noise_implied_force(robot: Robot, q: np.ndarray, frame: str, sigma_tau: float | np.ndarray) -> float:
    """RMS norm of the force that white torque noise σ_τ implies at ``frame``: F = (Jᵀ)⁺ τ, so
    E|F|² = tr((Jᵀ)⁺ diag(σ²) (Jᵀ)⁺ᵀ), J the linear Jacobian (LOCAL_WORLD_ALIGNED) at q."""
    model = robot.model
    data = model.createData()
    J = pin.computeFrameJacobian(model, data, np.asarray(q, float), robot.frame_id(frame), pin.LOCAL_WORLD_ALIGNED)[:3]
    P = np.linalg.pinv(J.T)
    sig = np.broadcast_to(np.asarray(sigma_tau, float), (J.shape[1],))
    return float(np.sqrt(np.trace(P @ np.diag(sig**2) @ P.T)))


def held_arm_scenario(seed: int = 0, *, robot: str = "ur5", frame: str = "tool0", duration: float = 60.0,
                      n_pushes: int = 5, train_duration: float = 30.0, log_rate: float = 500.0,
                      noise: NoiseSpec | None = None, t0: float = 1_712_345_678.0) -> HeldArmScenario:
    """A seeded held-still arm with stiction pushed ``n_pushes`` times (module docstring).

    Coulomb levels U(0.5, 1) × (2.5, 3, 2, 0.8, 0.6, 0.5) N·m (first six joints), static
    friction 1.3–1.7 × Coulomb; a pose near a bent-elbow one; pushes of 30–50 N for 0.6–1.2 s
    at ``frame``, one every duration/(n + 1) s, each in a random direction that loads some joint
    beyond twice its static friction (a push that breaks no stiction changes nothing logged);
    stamps from ``t0`` (Unix time, like a real logger). The training log tracks a Fourier
    reference at 250 Hz."""
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth

    rng = np.random.default_rng(seed)
    nom = load_robot(robot)
    truth = perturbed_truth(nom, rng=seed)
    n = nom.nv
    fc = rng.uniform(0.5, 1.0, n) * np.resize([2.5, 3.0, 2.0, 0.8, 0.6, 0.5], n)
    st = Stiction(fc, fc * rng.uniform(1.3, 1.7, n), 0.05)
    base = np.resize([0.3, -1.2, 1.4, -1.6, -1.5, 0.2], n)
    hold = base + rng.uniform(-0.3, 0.3, n)
    noise = NoiseSpec(q=1e-5, v=2e-3, tau=0.05) if noise is None else noise
    model, data = nom.model, nom.model.createData()
    J = pin.computeFrameJacobian(model, data, hold, nom.frame_id(frame), pin.LOCAL_WORLD_ALIGNED)[:3]
    pushes, gap = [], duration / (n_pushes + 1)
    for i in range(n_pushes):
        while True:
            d = rng.normal(size=3)
            F = d / np.linalg.norm(d) * rng.uniform(30.0, 50.0)
            if np.max(np.abs(J.T @ F) / st.fs) >= 2.0:
                break
        start = gap * (i + 1) + rng.uniform(-0.2, 0.2) * gap
        pushes.append(Push(float(start), float(start + rng.uniform(0.6, 1.2)), tuple(map(float, F)), frame))
    train, _ = simulate_held_arm(truth, nom, st, [], duration=train_duration, log_rate=250.0, noise=noise,
                                 seed=seed + 1000, base_freq=0.05)
    clean, gt = simulate_held_arm(truth, nom, st, pushes, hold=hold, duration=duration, log_rate=log_rate, seed=seed)
    r2 = np.random.default_rng(seed + 1)
    log = clean.with_(t=t0 + clean.t, q=add_white_noise(clean.q, noise.q, r2), v=add_white_noise(clean.v, noise.v, r2),
                      tau=add_white_noise(clean.tau, noise.tau, r2))
    moving = np.any(clean.v != 0.0, axis=1) | gt.active
    last = np.maximum.accumulate(np.where(moving, np.arange(len(moving)), -(10**9)))
    still = (gt.t - gt.t[np.maximum(last, 0)] >= 0.5) & (last >= 0) | (last < 0) & (gt.t >= 0.5)
    still &= ~gt.active
    return HeldArmScenario(robot, train, log, gt, still, hold, st, noise,
                           noise_implied_force(nom, hold, frame, noise.tau))

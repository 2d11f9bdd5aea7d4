"""Synthetic data for tests: fixed-base logs with known ground truth, computed independently of the regressor
(no simulator; the MuJoCo scenes and studies are the separate ``sensorless-studies`` package).

Torques come from Pinocchio's RNEA on the true model plus the true joint terms

    τ = rnea(q, v, v̇) + Ia v̇ + fv v + fc sgn(v) + o  (+ Gaussian noise σ)

so identification tests compare against physics, not against the regressor itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin

from .data.trajectory import Trajectory
from .robot import Robot

__all__ = ["NoiseSpec", "RealArtefacts", "TruthModel", "add_white_noise", "map_body_inertias", "one_joint_at_a_time",
           "perturbed_truth", "rest_segments", "streamed_fourier_log", "synthetic_trajectory", "with_real_artefacts"]


@dataclass
class TruthModel:
    """A robot with known inertial parameters and joint terms (per actuated joint)."""

    robot: Robot
    fv: np.ndarray
    fc: np.ndarray
    offset: np.ndarray
    armature: np.ndarray

    def torques(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Actuated-joint torques (N, n_actuated) by RNEA + joint terms."""
        r = self.robot
        model = r.model.copy()
        model.armature[:] = 0.0
        data = model.createData()
        act = r.actuated_v_indices
        tau = np.empty((Q.shape[0], r.n_actuated))
        for i in range(Q.shape[0]):
            tau[i] = pin.rnea(model, data, Q[i], V[i], A[i])[act]
        v, a = V[:, act], A[:, act]
        return tau + self.armature * a + self.fv * v + self.fc * np.sign(v) + self.offset

    def parameters(self, joint_terms=("fv", "fc", "offset", "armature")) -> np.ndarray:
        """Standard parameter vector in the layout of :class:`~sensorless.regressor.ModelStructure`."""
        per_joint = np.stack([getattr(self, t) for t in joint_terms], axis=1) if joint_terms else np.zeros((0,))
        return np.concatenate([self.robot.inertial_parameters(), per_joint.ravel()])


def map_body_inertias(robot: Robot, new_inertia: Callable[[pin.Inertia], pin.Inertia]) -> Robot:
    """A copy ``<name>_truth`` of ``robot`` whose every massive body's inertia ``I`` is
    ``new_inertia(I)`` (called body by body in joint order; massless bodies are kept)."""
    model = robot.model.copy()
    for j in range(1, model.njoints):
        if model.inertias[j].mass > 0:
            model.inertias[j] = new_inertia(model.inertias[j])
    return Robot(model, name=robot.name + "_truth", source=robot.source, actuated_joints=robot.actuated_joints)


def perturbed_truth(
    robot: Robot,
    *,
    rng: np.random.Generator | int = 0,
    mass_scale: float = 0.2,
    com_shift: float = 0.02,
    friction: bool = True,
    armature: float | None = 0.05,
) -> TruthModel:
    """A physically consistent 'true' robot near the nominal one, with friction.

    Each body's mass is scaled by U(1 ± mass_scale), its CoM shifted by up to ``com_shift`` m
    and its rotational inertia about the CoM scaled by the same factor (stays consistent).
    """
    rng = np.random.default_rng(rng)

    def scaled(I: pin.Inertia) -> pin.Inertia:
        s = 1.0 + mass_scale * rng.uniform(-1, 1)
        return pin.Inertia(I.mass * s, I.lever + rng.uniform(-com_shift, com_shift, 3), I.inertia * s)

    true = map_body_inertias(robot, scaled)
    n = robot.n_actuated
    fv = rng.uniform(0.05, 0.5, n) if friction else np.zeros(n)
    fc = rng.uniform(0.1, 1.0, n) if friction else np.zeros(n)
    off = rng.uniform(-0.3, 0.3, n) if friction else np.zeros(n)
    ia = np.full(n, armature) * rng.uniform(0.5, 1.5, n) if armature else np.zeros(n)
    return TruthModel(true, fv, fc, off, ia)


@dataclass(frozen=True)
class NoiseSpec:
    """Standard deviations of the white Gaussian noise added to the logged signals."""

    q: float = 1e-4  # rad (encoder)
    v: float = 1e-2  # rad/s
    tau: float = 0.02  # N·m (motor current x torque constant)
    base_position: float = 1e-3  # m
    base_orientation: float = 2e-3  # rad (random rotation vector, base frame)
    base_linear_velocity: float = 1e-2  # m/s
    base_angular_velocity: float = 1e-2  # rad/s
    imu_acc: float = 3e-2  # m/s² (accelerometer at the base origin, base axes)

    @classmethod
    def none(cls) -> NoiseSpec:
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def add_white_noise(x: np.ndarray, sigma: float | np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``x + σ ⊙ n`` with n ~ N(0, I) drawn from ``rng`` (a new array; nothing drawn when every σ is 0)."""
    if np.any(np.asarray(sigma) > 0):
        return x + rng.normal(size=x.shape) * sigma
    return x.copy()


def synthetic_trajectory(
    truth: TruthModel,
    motion: Trajectory,
    *,
    noise_std: float | np.ndarray = 0.0,
    rng: np.random.Generator | int = 0,
) -> Trajectory:
    """Fill ``motion`` (q, v, a of a fixed-base robot) with true torques + noise."""
    rng = np.random.default_rng(rng)
    r = truth.robot
    Q = r.full_configuration(motion.q)
    V = r.full_velocity(motion.v)
    A = r.full_velocity(motion.a)
    tau = add_white_noise(truth.torques(Q, V, A), noise_std, rng)
    full = np.zeros((len(motion), len(r.joint_names)))
    cols = [r.joint_names.index(j) for j in r.actuated_joints]
    full[:, cols] = tau
    return motion.with_(tau=full, source=f"<synthetic {r.name}>")


def streamed_fourier_log(
    truth: TruthModel,
    fourier,
    *,
    rate: float,
    n_samples: int,
    chunk: int = 10_000,
    noise_std: float = 0.0,
    rng: np.random.Generator | int = 0,
):
    """Yield a long synthetic Fourier log chunk by chunk (constant memory)."""
    rng = np.random.default_rng(rng)
    for start in range(0, n_samples, chunk):
        t = (start + np.arange(min(chunk, n_samples - start))) / rate
        q, v, a = fourier.evaluate(t)
        motion = Trajectory(t=t, q=q, v=v, a=a, joint_names=fourier.joint_names, source="<stream>")
        yield synthetic_trajectory(truth, motion, noise_std=noise_std, rng=rng)


@dataclass(frozen=True)
class RealArtefacts:
    """What a real recording adds to a clean simulated log (issues #39/#40: the honesty layer must hold on these).

    - ``q_step``: encoder quantum (rad, or m on a prismatic joint; a scalar or per joint): q ← step·round(q/step);
    - ``decimals``: q and v written with this many decimals (a UR logs 4): x ← round(x, decimals);
    - ``gain_error``: the logged torque is (1 + e)·τ per joint (a current times a torque constant off by e);
    - ``holding``: on a joint at rest (|v| < ``rest_speed``) the drive holds an extra torque drawn once per
      rest segment from U(−holding, holding) (stiction and holding current: the position loop's integrator);
    - ``stiffness``: unmodelled joint flexibility; the encoder sits on the motor side, so the logged
      q = q_link + τ/k (N·m/rad);
    - ``jitter``: the time stamps carry white noise of this std (s); the samples are where they were.
    """

    q_step: float | np.ndarray = 0.0
    decimals: int | None = None
    gain_error: float | np.ndarray = 0.0
    holding: float | np.ndarray = 0.0
    rest_speed: float = 1e-3
    stiffness: float | np.ndarray = np.inf
    jitter: float = 0.0

    def settings(self) -> dict:
        """The artefacts as plain values (benchmark records carry them)."""
        def plain(x):
            a = np.asarray(x, float)
            return a.tolist() if a.ndim else (None if not np.isfinite(a) else float(a))
        return {"q_step": plain(self.q_step), "decimals": self.decimals, "gain_error": plain(self.gain_error),
                "holding": plain(self.holding), "rest_speed": self.rest_speed, "stiffness": plain(self.stiffness),
                "jitter": self.jitter}


def rest_segments(still: np.ndarray) -> list[slice]:
    """The runs of True in a boolean vector, as slices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2])]


def with_real_artefacts(traj: Trajectory, artefacts: RealArtefacts, rng: np.random.Generator | int = 0,
                        joints: Sequence[str] | None = None) -> Trajectory:
    """``traj`` as a lab would have logged it (:class:`RealArtefacts`), on ``joints`` (default: every column).

    The true torque is used for the holding torque and the deflection; the returned log keeps v̇ only
    when the input had none (a real log has no measured acceleration: ``a`` is dropped). Its provenance
    records the artefacts."""
    rng = np.random.default_rng(rng)
    cols = [traj.joint_names.index(j) for j in joints] if joints is not None else list(range(traj.q.shape[1]))
    q, v = traj.q.copy(), None if traj.v is None else traj.v.copy()
    tau = None if traj.tau is None else traj.tau.copy()
    qs, vs = q[:, cols], None if v is None else v[:, cols]
    if tau is not None:
        ts = tau[:, cols]
        if np.any(np.asarray(artefacts.holding) > 0) and vs is not None:
            hold = np.broadcast_to(np.asarray(artefacts.holding, float), (len(cols),))
            for k in range(len(cols)):
                for seg in rest_segments(np.abs(vs[:, k]) < artefacts.rest_speed):
                    ts[seg, k] += rng.uniform(-hold[k], hold[k])
        k_joint = np.broadcast_to(np.asarray(artefacts.stiffness, float), (len(cols),))
        qs = qs + np.where(np.isfinite(k_joint), ts / np.where(np.isfinite(k_joint), k_joint, 1.0), 0.0)
        ts = ts * (1.0 + np.broadcast_to(np.asarray(artefacts.gain_error, float), (len(cols),)))
        tau[:, cols] = ts
    step = np.broadcast_to(np.asarray(artefacts.q_step, float), (len(cols),))
    qs = np.where(step > 0, np.round(qs / np.where(step > 0, step, 1.0)) * step, qs)
    if artefacts.decimals is not None:
        qs = np.round(qs, artefacts.decimals)
        if vs is not None:
            vs = np.round(vs, artefacts.decimals)
    q[:, cols] = qs
    if v is not None:
        v[:, cols] = vs
    t = traj.t + (rng.normal(0.0, artefacts.jitter, traj.t.shape) if artefacts.jitter > 0 else 0.0)
    if artefacts.jitter > 0:
        t = np.maximum.accumulate(t)  # stamps stay ordered: a logger never writes them backwards
    prov = dict(traj.provenance, artefacts=artefacts.settings())
    return traj.with_(t=t, q=q, v=v, a=None, tau=tau, provenance=prov)


def one_joint_at_a_time(t: np.ndarray, q0: np.ndarray, amplitude: float | np.ndarray = 0.6,
                        period: float = 4.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A single-joint protocol (q, v, v̇): joint k sweeps q0_k + A_k·(1 − cos 2πt/T)/2 over its share of
    ``t`` (whole periods near T) while every other joint is held at ``q0`` (the logs that move one joint at a time)."""
    n = len(q0)
    amp = np.broadcast_to(np.asarray(amplitude, float), (n,))
    q = np.tile(np.asarray(q0, float), (len(t), 1))
    v, a = np.zeros_like(q), np.zeros_like(q)
    share = np.array_split(np.arange(len(t)), n)
    for k, idx in enumerate(share):
        if len(idx) < 2:
            continue
        tk = t[idx] - t[idx[0]]
        span = t[min(idx[-1] + 1, len(t) - 1)] - t[idx[0]]
        w = 2 * np.pi * max(1, round(span / period)) / span  # whole periods: the joint ends where it began, at rest
        q[idx, k] += amp[k] * (1 - np.cos(w * tk)) / 2
        v[idx, k] = amp[k] * w * np.sin(w * tk) / 2
        a[idx, k] = amp[k] * w * w * np.cos(w * tk) / 2
    return q, v, a

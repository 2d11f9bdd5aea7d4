"""Floating-base logs with measured contact wrenches that solve the dynamics exactly.

Motion: joints q_j(t) = q0_j + e(t) s_j(t) with s a random multi-sine and e a C² ramp from
0 (a standing window of ``stand`` seconds, v = v̇ = 0) to 1; the base twist (LOCAL) is
e(t) s_b(t), its derivative is the base acceleration, and the base pose is integrated
with Pinocchio (``pin.integrate``, sub-stepped), so q, v, v̇ are consistent.

Wrenches: the floating-base rows of RNEA on the *true* model, τ_b = [M v̇ + h]_base, are
split over the active contacts by the minimum-norm solution of Σ_k [J_kᵀ]_base f_k = τ_b
(Jacobians in LOCAL_WORLD_ALIGNED, as :mod:`sensorless.regressor.contact` expects).
Joint torques, when asked for, are τ = [M v̇ + h]_joints − [Jcᵀ f]_joints. A measurement
bias is then added to the logged wrenches: ``bias`` (n_contacts, 3) forces, in each
contact's own (sole) frame or in world axes (``bias_frame``).
"""

from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.robot import Robot

__all__ = ["accelerometer_reading", "wrench_log", "walking_flags"]


def _ramp(t: np.ndarray, t0: float, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic smoothstep e(t) from 0 (t ≤ t0) to 1 (t ≥ t0 + width) and its two derivatives."""
    x = np.clip((t - t0) / width, 0.0, 1.0)
    e = x**3 * (10 - 15 * x + 6 * x**2)
    de = 30 * x**2 * (1 - x) ** 2 / width
    dde = 60 * x * (1 - x) * (1 - 2 * x) / width**2
    return e, de, dde


def _multisine(t, n, amp, freqs, rng):
    """(s, ṡ, s̈) of n random multi-sines, shape (N, n) each."""
    A = amp * rng.uniform(0.3, 1.0, (len(freqs), n)) / len(freqs)
    ph = rng.uniform(0, 2 * np.pi, (len(freqs), n))
    w = 2 * np.pi * np.asarray(freqs)[:, None, None]
    arg = w * t[None, :, None] + ph[:, None, :]
    s = np.sum(A[:, None, :] * np.sin(arg), axis=0)
    ds = np.sum(A[:, None, :] * w * np.cos(arg), axis=0)
    dds = -np.sum(A[:, None, :] * w**2 * np.sin(arg), axis=0)
    return s, ds, dds


def walking_flags(n: int, n_contacts: int, period: int) -> np.ndarray:
    """Contact flags cycling through double support and single support on each contact
    (all, only 0, all, only 1, …), ``period`` samples per phase."""
    phase = (np.arange(n) // period) % (2 * n_contacts)
    flags = np.ones((n, n_contacts), bool)
    single = phase % 2 == 1
    for k in range(n_contacts):
        flags[single & (phase // 2 == k)] = False
        flags[single & (phase // 2 == k), k] = True
    return flags


def wrench_log(
    truth: Robot,
    frames: Sequence[str],
    *,
    duration: float = 10.0,
    rate: float = 100.0,
    stand: float = 1.0,
    joint_amplitude: float = 0.3,
    base_amplitude: tuple[float, float] = (0.3, 0.6),
    freqs: Sequence[float] = (0.2, 0.35, 0.55, 0.8),
    flags: np.ndarray | None = None,
    bias: np.ndarray | None = None,
    bias_frame: str = "sole",
    torques: bool = False,
    noise: float = 0.0,
    seed: int = 0,
    q0: np.ndarray | None = None,
    dims: int = 6,
    wrench_frames: Sequence[str] | None = None,
) -> Trajectory:
    """A log of ``truth`` with 6-D contact wrenches at ``frames`` (module docstring).

    ``base_amplitude`` = (linear [m/s], angular [rad/s]) peak twist; ``flags`` (N, n_contacts)
    default all in contact; ``noise`` is the std of Gaussian noise on the wrenches [N, N·m].
    ``dims`` = 3 gives point contacts (forces only). ``extras``: ``contact`` flags and
    ``contact_forces`` (N, n_contacts, dims). ``wrench_frames`` (one model frame per contact, e.g. a sole
    or an F/T sensor) writes each wrench in that frame's axes about its origin instead, as such a sensor
    logs it: f_S = R_Sᵀ f, τ_S = R_Sᵀ (τ_C − (p_S − p_C) × f) (``--wrench-frame`` undoes it).
    """
    rng = np.random.default_rng(seed)
    model = truth.model.copy()
    model.armature[:] = 0.0
    data = model.createData()
    fids = [model.getFrameId(f) for f in frames]
    n = int(round(duration * rate))
    t = np.arange(n) / rate
    e, de, dde = (x[:, None] for x in _ramp(t, stand, 1.0))
    nj = truth.nv - 6
    s, ds, dds = _multisine(t, nj, joint_amplitude, freqs, rng)
    qj0 = np.zeros(nj) if q0 is None else np.asarray(q0, float)
    qj, vj, aj = qj0 + e * s, de * s + e * ds, dde * s + 2 * de * ds + e * dds
    sb, dsb, ddsb = _multisine(t, 6, 1.0, freqs, rng)
    scale = np.repeat(np.asarray(base_amplitude, float), 3)
    vb, ab = scale * e * sb, scale * (de * sb + e * dsb)
    # base pose: integrate the LOCAL twist with sub-steps (midpoint twist)
    base_q = np.empty((n, 7))
    qb = pin.neutral(model)[:7]
    qb[2] = 1.0
    sub = 20
    for i in range(n):
        base_q[i] = qb
        if i + 1 < n:
            for k in range(sub):
                a = (k + 0.5) / sub
                qb = pin.integrate(_ff_model(), qb, ((1 - a) * vb[i] + a * vb[i + 1]) / (rate * sub))
    if flags is None:
        flags = np.ones((n, len(frames)), bool)
    flags = np.asarray(flags, bool)
    Q = truth.full_configuration(qj, base_q)
    V = truth.full_velocity(vj, vb)
    A = truth.full_velocity(aj, ab)
    forces = np.zeros((n, len(frames), dims))
    tau = np.zeros((n, nj))
    act = np.array([truth.v_index(j) for j in truth.joint_names])
    unbalanced: list[int] = []
    for i in range(n):
        full = pin.rnea(model, data, Q[i], V[i], A[i])
        pin.computeJointJacobians(model, data, Q[i])
        on = np.flatnonzero(flags[i])
        J = np.concatenate([pin.getFrameJacobian(model, data, fids[k], pin.LOCAL_WORLD_ALIGNED)[:dims] for k in on])
        f = np.linalg.lstsq(J[:, :6].T, full[:6], rcond=None)[0]
        gap = np.abs(J[:, :6].T @ f - full[:6]).max()
        if gap > 1e-6 * max(np.abs(full[:6]).max(), 1.0):
            unbalanced.append(i)
        forces[i, on] = f.reshape(-1, dims)
        tau[i] = (full - J.T @ f)[act]
    if unbalanced:
        warnings.warn(f"wrench_log: on {len(unbalanced)} of {n} samples (first: {unbalanced[0]}) the contacts in "
                      f"flags cannot produce the base wrench the motion needs (e.g. {dims}-D forces at fewer than "
                      "three points); the log is not consistent with any rigid-body model there", RuntimeWarning,
                      stacklevel=2)
    measured = forces.copy()
    if bias is not None:
        b = np.asarray(bias, float).reshape(len(frames), 3)
        if bias_frame == "sole":
            for i in range(n):
                pin.framesForwardKinematics(model, data, Q[i])
                for k, fid in enumerate(fids):
                    measured[i, k, :3] += data.oMf[fid].rotation @ b[k]
        else:
            measured[:, :, :3] += b
    if noise:
        measured += rng.normal(scale=noise, size=measured.shape)
    if wrench_frames is not None:
        measured = _in_frames(model, data, Q, fids, [model.getFrameId(f) for f in wrench_frames], measured)
    return Trajectory(
        t=t, q=qj, v=vj, a=aj, tau=tau if torques else None, base_q=base_q, base_v=vb, base_a=ab,
        joint_names=truth.joint_names, extras={"contact": flags, "contact_forces": measured},
        source=f"<wrench_log {truth.name}>",
    )


def accelerometer_reading(robot: Robot, traj: Trajectory, frame: str, g: float = 9.81) -> np.ndarray:
    """(N, 3) specific force f_s = R_sᵀ (p̈_s − g) [m/s²] an accelerometer at model frame ``frame`` reads,
    in that frame's axes, from a floating-base log with q, v, a, base_q, base_v, base_a (base twist
    LOCAL); p̈_s is the frame's classical acceleration (Pinocchio). It reads +g up at rest;
    :func:`sensorless.data.imu_frame_base_acceleration` inverts it."""
    model = robot.model.copy()
    data = model.createData()
    fid = model.getFrameId(frame)
    perm = robot.joint_order(traj.joint_names, traj.source)
    Q = robot.full_configuration(traj.q[:, perm], traj.base_q)
    V = robot.full_velocity(traj.v[:, perm], traj.base_v)
    A = robot.full_velocity(traj.a[:, perm], traj.base_a)
    gvec = np.array([0.0, 0.0, -g])
    out = np.empty((len(Q), 3))
    for i in range(len(Q)):
        pin.forwardKinematics(model, data, Q[i], V[i], A[i])
        R = pin.updateFramePlacement(model, data, fid).rotation
        out[i] = R.T @ (pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear - gvec)
    return out


def _in_frames(model, data, Q, contacts, sensors, w):
    """World-aligned wrenches at the contact frames ``w`` (N, n, 3|6) in the LOCAL frames ``sensors``."""
    out = w.copy()
    for i in range(len(Q)):
        pin.framesForwardKinematics(model, data, Q[i])
        for k, (c, s) in enumerate(zip(contacts, sensors)):
            R, f = data.oMf[s].rotation, w[i, k, :3]
            out[i, k, :3] = R.T @ f
            if w.shape[2] == 6:
                out[i, k, 3:] = R.T @ (w[i, k, 3:] - np.cross(data.oMf[s].translation - data.oMf[c].translation, f))
    return out


_FF: list = []


def _ff_model() -> pin.Model:
    """A model with only a free-flyer joint (for pin.integrate on the base pose)."""
    if not _FF:
        m = pin.Model()
        m.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
        _FF.append(m)
    return _FF[0]

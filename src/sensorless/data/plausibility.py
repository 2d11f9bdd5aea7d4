"""Drive gains against the robot model: torques τ = K·i no model with friction can produce are refused.

The model (the robot description's own inertials, the prior) predicts the rigid-body joint torques
of the log by inverse dynamics on up to :data:`SAMPLES` samples; ``rigid_j`` is their RMS. A real
drive also carries friction, and on a joint held still, stiction and the position loop's holding
current: any torque up to the Coulomb level, whatever the rigid body asks. So each joint gets a
generous friction bound ``friction_j = fc_max_j + fv_max_j · rms(v_j)``, with
``fc_max_j = FRICTION_SHARE · effort_j`` (the description's effort limit; without one, the largest
joint's rigid-body RMS) and ``fv_max_j = fc_max_j / (1 rad/s)``. Then, per joint with a gain:

* too large: ``rms(τ_j) > HIGH · (rigid_j + friction_j)``: :data:`HIGH` (30) times more than any
  prior-plus-friction torque (the model has no payload: a load heavier than the whole arm reached 10×; a
  torque constant in mN·m/A is 1000×);
* too small: on the samples where joint j moves (``|v_j| >`` :data:`MOVING`), the measured RMS below
  1/:data:`RATIO` of the model's: friction opposes the motion, so over a sweep up and down it cannot
  cancel the rigid-body torque (a held-still joint, whose gravity stiction may hold, is not judged on this).

Either is a :class:`~sensorless.errors.UnitsError` naming the joint, its gain and the comparison: a
gain in the wrong unit (mN·m/A, per motor instead of per joint, a missing gear ratio).
``--accept-implausible-gains`` (``accept_implausible_gains=True``) skips this check and no other.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import UnitsError, setting
from .trajectory import Trajectory

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["check_gain_plausibility", "model_torque_bounds", "RATIO", "HIGH", "FRICTION_SHARE"]

#: allowed factor below the torque the model needs beyond what friction can hold
RATIO = 100.0
#: allowed factor above what the model plus the friction bound can produce
HIGH = 30.0
#: the Coulomb bound: this share of the joint's effort limit (generous: harmonic drives reach 10–30 %)
FRICTION_SHARE = 0.5
#: a joint moves on a sample faster than this (rad/s or m/s)
MOVING = 1e-3
#: samples the model is evaluated on
SAMPLES = 400


def model_torque_bounds(traj: Trajectory, robot: "Robot") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per joint (``traj.joint_names`` = ``robot.joint_names`` order): ``(rigid, friction, tau, idx)``, the RMS
    of the model's inverse dynamics τ = M(q)v̇ + C(q, v)v + g(q) over the log, the friction bound (module
    docstring), and that torque ``tau`` (n, joints) on the samples ``idx`` it was evaluated on."""
    import pinocchio as pin

    idx = np.unique(np.linspace(0, len(traj) - 1, min(SAMPLES, len(traj))).astype(int))
    q = robot.full_configuration(traj.q[idx], None if traj.base_q is None else traj.base_q[idx])
    zeros = np.zeros((idx.size, len(traj.joint_names)))
    v = robot.full_velocity(zeros if traj.v is None else traj.v[idx], None if traj.base_v is None else traj.base_v[idx])
    a = robot.full_velocity(zeros if traj.a is None else traj.a[idx], None if traj.base_a is None else traj.base_a[idx])
    data = robot.model.createData()
    cols = [robot.v_index(n) for n in robot.joint_names]
    tau = np.array([pin.rnea(robot.model, data, q[k], v[k], a[k])[cols] for k in range(idx.size)])
    rigid = np.sqrt(np.mean(tau**2, axis=0))
    effort = np.asarray(robot.model.effortLimit, dtype=float)[cols]
    fallback = max(float(rigid.max()) if rigid.size else 0.0, 1e-6)
    fc = FRICTION_SHARE * np.where(np.isfinite(effort) & (effort > 0) & (effort < 1e6), effort, fallback)
    speed = np.sqrt(np.mean((zeros if traj.v is None else traj.v[idx]) ** 2, axis=0))
    return rigid, fc + fc * speed, tau, idx


def check_gain_plausibility(traj: Trajectory, robot: "Robot | None") -> None:
    """UnitsError for a joint whose torques from currents are implausible for ``robot`` (module docstring)."""
    gains = traj.provenance.get("gains")
    if robot is None or not gains or traj.tau is None or list(traj.joint_names) != list(robot.joint_names):
        return
    rigid, friction, model, idx = model_torque_bounds(traj, robot)
    tau = np.asarray(traj.tau, dtype=float)
    rms = np.sqrt(np.mean(tau**2, axis=0))
    moving = np.abs(traj.v[idx]) > MOVING if traj.v is not None else np.zeros(model.shape, dtype=bool)
    for j, name in enumerate(traj.joint_names):
        if name not in gains:
            continue
        mv = moving[:, j]
        need = float(np.sqrt(np.mean(model[mv, j] ** 2))) if mv.any() else 0.0
        got = float(np.sqrt(np.mean(tau[idx[mv], j] ** 2))) if mv.any() else 0.0
        if rms[j] > HIGH * (rigid[j] + friction[j]):
            why = (f"{rms[j] / (rigid[j] + friction[j]):.3g}× the most the robot model ({rigid[j]:.3g} N·m RMS) plus a "
                   f"generous friction bound ({friction[j]:.3g} N·m) can produce over this log; more than {HIGH:g}×")
        elif mv.any() and got < need / RATIO:
            why = (f"{got:.3g} N·m RMS while the joint moves, below 1/{RATIO:g} of the {need:.3g} N·m the robot model "
                   "needs there (friction opposes the motion, so it cannot cancel that torque)")
        else:
            continue
        raise UnitsError(
            f"joint '{name}': drive gain {gains[name]:g} makes torques of RMS {rms[j]:.3g} N·m, {why}: a gain in "
            f"the wrong unit? Check {setting('gains')}, or keep it with {setting('accept_implausible_gains', True)}",
            traj.source)

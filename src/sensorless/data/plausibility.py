"""Drive gains against the robot model: torques τ = K·i far off the model's torque scale are refused.

The model (the robot description's own inertials, the prior) predicts the joint torques of the
log by inverse dynamics on up to :data:`SAMPLES` samples. Per joint, the torque scale is the RMS
of that prediction, floored at :data:`FLOOR` of the largest joint's (a joint the model barely
loads still carries friction). A joint whose gain-made torques have an RMS more than
:data:`RATIO` times that scale, or less than 1/:data:`RATIO` of it, is a
:class:`~sensorless.errors.UnitsError` naming the joint and its gain: a gain in the wrong unit
(mN·m/A, per motor instead of per joint, a missing gear ratio). ``--accept-implausible-gains``
(``accept_implausible_gains=True``) skips the check.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import UnitsError, setting
from .trajectory import Trajectory

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["check_gain_plausibility", "RATIO"]

#: allowed factor between gain-made torques and the model's torque scale, either way
RATIO = 100.0
#: a joint's torque scale is at least this share of the largest joint's
FLOOR = 0.01
#: samples the model is evaluated on
SAMPLES = 400


def model_torque_scale(traj: Trajectory, robot: "Robot") -> np.ndarray:
    """Per joint (``traj.joint_names`` = ``robot.joint_names`` order): RMS of the model's inverse
    dynamics τ = M(q)v̇ + C(q, v)v + g(q) over the log, floored (module docstring)."""
    import pinocchio as pin

    idx = np.unique(np.linspace(0, len(traj) - 1, min(SAMPLES, len(traj))).astype(int))
    q = robot.full_configuration(traj.q[idx], None if traj.base_q is None else traj.base_q[idx])
    zeros = np.zeros((idx.size, len(traj.joint_names)))
    v = robot.full_velocity(zeros if traj.v is None else traj.v[idx], None if traj.base_v is None else traj.base_v[idx])
    a = robot.full_velocity(zeros if traj.a is None else traj.a[idx], None if traj.base_a is None else traj.base_a[idx])
    data = robot.model.createData()
    cols = [robot.v_index(n) for n in robot.joint_names]
    tau = np.array([pin.rnea(robot.model, data, q[k], v[k], a[k])[cols] for k in range(idx.size)])
    rms = np.sqrt(np.mean(tau**2, axis=0))
    return np.maximum(rms, max(FLOOR * float(rms.max()), 1e-6))


def check_gain_plausibility(traj: Trajectory, robot: "Robot | None") -> None:
    """UnitsError for a joint whose torques from currents are implausible for ``robot`` (module docstring)."""
    gains = traj.provenance.get("gains")
    if robot is None or not gains or traj.tau is None or list(traj.joint_names) != list(robot.joint_names):
        return
    scale = model_torque_scale(traj, robot)
    rms = np.sqrt(np.mean(np.asarray(traj.tau, dtype=float) ** 2, axis=0))
    for j, name in enumerate(traj.joint_names):
        if name not in gains:
            continue
        ratio = rms[j] / scale[j]
        if ratio > RATIO or ratio < 1 / RATIO:
            raise UnitsError(
                f"joint '{name}': drive gain {gains[name]:g} makes torques of RMS {rms[j]:.3g} N·m, "
                f"{ratio:.3g}× the torque scale the robot model predicts over this log ({scale[j]:.3g} N·m); "
                f"outside 1/{RATIO:g}..{RATIO:g}×: a gain in the wrong unit? Check {setting('gains')}, or keep it "
                f"with {setting('accept_implausible_gains', True)}", traj.source)

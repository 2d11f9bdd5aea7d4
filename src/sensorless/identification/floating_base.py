"""Checks of a floating-base model identified from measured contact wrenches.

* :func:`base_wrench_metrics`: the residual of the 6 floating-base rows, e = W π − y
  (Pinocchio's LOCAL base frame: force, and moment about the base origin), rotated to
  world axes, e_w = R e, and summarised as RMSE per axis and of the norm [N], [N·m].
* :func:`com_cop_check`: on standing windows (quasi-static: joint and base velocities below
  a threshold for a minimum time) the horizontal CoM of the identified model must lie over
  the centre of pressure of the measured wrenches (bias removed). The CoP on the plane z₀
  of the active contacts, from F = Σ f_k and the moment about the world origin
  M = Σ (τ_k + p_k × f_k):  x = (z₀ F_x − M_y) / F_z,  y = (M_x + z₀ F_y) / F_z.
  The CoM is c(q) = Σ_k (m_k p_k + R_k h_k) / Σ m_k (h_k = m_k c_k, first moments), so
  non-physical parameter vectors are fine.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError
from ..regressor.contact import ContactStructure
from ..regressor.terms import in_robot_order

__all__ = ["base_wrench_metrics", "com_cop_check", "com_positions", "standing_mask"]


def _wrench_structure(structure) -> ContactStructure:
    if not getattr(structure, "measured_wrench", False):  # the row map keeps Jcᵀ f on the known side
        raise DataError("base-wrench checks need a ContactStructure in mode 'wrench' (measured contact wrenches)")
    return structure


def base_wrench_metrics(structure: ContactStructure, params: np.ndarray, traj: Trajectory) -> dict:
    """World-axis RMSE of the base-wrench residual (module docstring), with the RMS of the
    measured base wrench for scale."""
    s = _wrench_structure(structure)
    pred, meas = s.torques(params, traj)[:, :6], s.target(traj)[:, :6]
    from scipy.spatial.transform import Rotation  # imported on use: scipy.spatial costs ~0.1 s at start-up

    R = Rotation.from_quat(np.asarray(in_robot_order(s.robot, traj).base_q)[:, 3:7]).as_matrix()
    err = np.einsum("nij,nkj->nki", R, (pred - meas).reshape(-1, 2, 3))  # (N, [force, moment], 3)
    ref = np.einsum("nij,nkj->nki", R, meas.reshape(-1, 2, 3))

    def rms(x):
        return np.sqrt(np.mean(x**2, axis=0))

    return {
        "axes": "world",
        "moment_about": "base origin",
        "n_samples": len(traj),
        "force_rmse": rms(err[:, 0]).tolist(),
        "force_rmse_norm": float(np.sqrt(np.mean(np.sum(err[:, 0] ** 2, axis=1)))),
        "moment_rmse": rms(err[:, 1]).tolist(),
        "moment_rmse_norm": float(np.sqrt(np.mean(np.sum(err[:, 1] ** 2, axis=1)))),
        "force_rms_measured_norm": float(np.sqrt(np.mean(np.sum(ref[:, 0] ** 2, axis=1)))),
        "moment_rms_measured_norm": float(np.sqrt(np.mean(np.sum(ref[:, 1] ** 2, axis=1)))),
    }


def com_positions(robot, inertial: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """World CoM (N, 3) of ``robot`` with body parameters ``inertial`` at configurations Q."""
    pi = np.asarray(inertial, float).reshape(-1, 10)
    M = pi[:, 0].sum()
    model, data = robot.model, robot.data
    out = np.empty((Q.shape[0], 3))
    for i in range(Q.shape[0]):
        pin.forwardKinematics(model, data, Q[i])
        out[i] = sum(pi[k, 0] * data.oMi[k + 1].translation + data.oMi[k + 1].rotation @ pi[k, 1:4]
                     for k in range(len(pi))) / M
    return out


def standing_mask(traj: Trajectory, flags: np.ndarray, speed: float = 0.02, min_duration: float = 0.3) -> np.ndarray:
    """Samples of quasi-static windows: max |v_joint| and ‖base twist‖ below ``speed``
    [rad/s, m/s], at least one contact active, for at least ``min_duration`` seconds."""
    still = np.max(np.abs(traj.v), axis=1) < speed if traj.v is not None and traj.n_joints else np.ones(len(traj), bool)
    if traj.base_v is not None:
        still &= np.linalg.norm(traj.base_v, axis=1) < speed
    still &= flags.any(axis=1)
    mask = np.zeros(len(traj), bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        if traj.t[b - 1] - traj.t[a] >= min_duration:
            mask[a:b] = True
    return mask


def com_cop_check(
    structure: ContactStructure,
    params: np.ndarray,
    traj: Trajectory,
    *,
    speed: float = 0.02,
    min_duration: float = 0.3,
    tolerance: float = 0.01,
) -> dict:
    """Horizontal CoM (identified and model-file) vs the measured CoP on standing windows.

    Returns the number of standing samples, the windows [t0, t1], the mean and max horizontal
    distance [m] for the identified parameters and for the model file's, and ``ok`` (mean
    distance ≤ ``tolerance``; None without standing windows).
    """
    s = _wrench_structure(structure)
    flags = s.contacts(traj)
    mask = standing_mask(traj, flags, speed, min_duration)
    out = {"n_samples": int(mask.sum()), "speed_threshold": speed, "min_duration": min_duration,
           "tolerance": tolerance, "windows": []}
    if not mask.any():
        return {**out, "ok": None}
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    out["windows"] = [[float(traj.t[a]), float(traj.t[b - 1])] for a, b in zip(edges[::2], edges[1::2])]
    part = traj.take(mask)
    fl = flags[mask]
    Q = s.robot.full_configuration(in_robot_order(s.robot, part).q, part.base_q)
    n_c = len(s.contact_frames)
    f = s.measured_wrenches(part)
    w = np.zeros((len(part), n_c, 6))
    start = 0
    for k, d in enumerate(s.contact_dims):
        w[:, k, :d] = f[:, start : start + d]
        start += d
    w -= s.force_bias(params, Q, fl)
    w *= fl[:, :, None]
    pos = np.empty((len(part), n_c, 3))
    for i in range(len(part)):
        pin.framesForwardKinematics(s.robot.model, s.robot.data, Q[i])
        for k, fid in enumerate(s._fids):
            pos[i, k] = s.robot.data.oMf[fid].translation
    pos[:, :, 2] -= np.array([s.contact_offset if d == 3 else 0.0 for d in s.contact_dims])
    F = w[:, :, :3].sum(axis=1)
    Mo = (w[:, :, 3:] + np.cross(pos, w[:, :, :3])).sum(axis=1)
    z0 = (pos[:, :, 2] * fl).sum(axis=1) / np.maximum(fl.sum(axis=1), 1)
    loaded = F[:, 2] > 1e-6 * np.abs(F).max()
    cop = np.stack([(z0 * F[:, 0] - Mo[:, 1]) / F[:, 2], (Mo[:, 0] + z0 * F[:, 1]) / F[:, 2]], axis=1)[loaded]
    nb = s.n_body_params
    d_id = np.linalg.norm(com_positions(s.robot, params[:nb], Q[loaded])[:, :2] - cop, axis=1)
    d_cad = np.linalg.norm(com_positions(s.robot, s.robot.inertial_parameters(), Q[loaded])[:, :2] - cop, axis=1)
    mean = float(d_id.mean()) if d_id.size else float("nan")
    return {
        **out,
        "distance_mean": mean,
        "distance_max": float(d_id.max()) if d_id.size else float("nan"),
        "urdf_distance_mean": float(d_cad.mean()) if d_cad.size else float("nan"),
        "urdf_distance_max": float(d_cad.max()) if d_cad.size else float("nan"),
        "ok": bool(mean <= tolerance) if d_id.size else None,
    }


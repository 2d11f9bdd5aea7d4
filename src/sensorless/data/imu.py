"""Base acceleration of a floating-base log, from an IMU accelerometer or the base twist.

Pinocchio's free-flyer acceleration (LOCAL frame) is the spatial acceleration

    a_b = [Rᵀp̈ − ω × v_b ;  ω̇],      v_b = Rᵀṗ,  ω the angular velocity (base frame).

An accelerometer rigidly mounted at ``r`` on the base, axes aligned with the base, reads the
specific force f = Rᵀ(p̈_r − g) with p̈_r = p̈ + R(ω̇ × r + ω × (ω × r)), so

    a_b,lin = f + Rᵀg − ω̇ × r − ω × (ω × r) − ω × v_b.

No differentiation is involved: the accelerometer's noise enters once, where
differentiating ``v_b`` amplifies its noise by ~1/dt. ω̇ still comes from differentiating ω
(the gyro, ``base_v[:, 3:]``), which is far less noisy than a linear-velocity estimate.
Logs store the reading as ``extras["imu_acc"]`` (N, 3) [m/s²] (NPZ/HDF5 key ``imu_acc``).

Sensor axes that differ from the base's (rotation R_bs, base ← sensor) give f = R_bs f_s
(``rotation``). An IMU named by a model frame (``imu_frame``, e.g. TALOS ``imu_link`` on
the torso) may sit on any body: with Pinocchio's forward kinematics at (q, v, v̇₀), v̇₀ the
accelerations with the base's linear part set to 0, the frame's classical acceleration is
p̈₀; the base's linear acceleration enters every point as R_b a_lin, so with
p̈_s = R_s f_s + g (R_s the frame's world rotation)

    a_b,lin = R_bᵀ (p̈_s − p̈₀),

which contains the lever arm, the frame rotation and the joint motion in between
(joint accelerations ``traj.a`` are needed unless the frame is on the base body).
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError, RobotModelError, ShapeMismatchError, setting, did_you_mean
from .filtering import SavitzkyGolay, note_processing, uniform_dt, default_savgol_window
from .trajectory import Trajectory

__all__ = ["IMU_KEY", "base_acceleration", "gravity_in_base", "imu_base_acceleration", "imu_frame_base_acceleration"]

IMU_KEY = "imu_acc"
STANDARD_GRAVITY = 9.81


def gravity_in_base(base_q: np.ndarray, g: float = STANDARD_GRAVITY) -> np.ndarray:
    """Rᵀ g for g = (0, 0, −g) in the world, from quaternions ``base_q[:, 3:7]`` = (x, y, z, w)."""
    quat = np.asarray(base_q, float)[:, 3:7]
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    x, y, z, w = quat.T
    # Rᵀ e_z = third row of R (as a column)
    ez = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
    return -g * ez


def imu_base_acceleration(
    base_q: np.ndarray,
    base_v: np.ndarray,
    imu_acc: np.ndarray,
    angular_acc: np.ndarray,
    offset: np.ndarray | None = None,
    g: float = STANDARD_GRAVITY,
    rotation: np.ndarray | None = None,
) -> np.ndarray:
    """(N, 6) LOCAL base acceleration from the accelerometer's specific force (module docstring).

    ``offset``: accelerometer position in the base frame [m]; ``rotation``: R_bs (3, 3), the
    sensor axes in base axes (default identity)."""
    base_v, imu_acc, angular_acc = (np.asarray(a, float) for a in (base_v, imu_acc, angular_acc))
    n = base_v.shape[0]
    for name, arr, cols in (("base_q", np.asarray(base_q), 7), ("base_v", base_v, 6), (IMU_KEY, imu_acc, 3),
                            ("angular_acc", angular_acc, 3)):
        if arr.shape != (n, cols):
            raise ShapeMismatchError(f"{name} has shape {arr.shape}; expected ({n}, {cols})")
    v, w = base_v[:, :3], base_v[:, 3:]
    if rotation is not None:
        imu_acc = imu_acc @ np.asarray(rotation, float).T
    lin = imu_acc + gravity_in_base(base_q, g) - np.cross(w, v)
    if offset is not None:
        r = np.broadcast_to(np.asarray(offset, float), (n, 3))
        lin = lin - np.cross(angular_acc, r) - np.cross(w, np.cross(w, r))
    return np.hstack([lin, angular_acc])


def imu_frame_base_acceleration(
    robot,
    traj: Trajectory,
    frame: str,
    angular_acc: np.ndarray,
    g: float = STANDARD_GRAVITY,
) -> np.ndarray:
    """(N, 6) LOCAL base acceleration from ``extras["imu_acc"]`` read in the model frame
    ``frame`` (rotation and lever arm from the model, on any body; module docstring)."""
    import pinocchio as pin  # imported on use (start-up time of the data layer)

    if not getattr(robot, "floating_base", False):
        raise RobotModelError(f"{robot.name}: an IMU frame needs a floating-base robot ({setting('floating_base', True)})")
    if not robot.model.existFrame(frame):
        names = [f.name for f in robot.model.frames]
        near = [n for n in names if "imu" in n.lower()]
        close = did_you_mean(frame, names)
        raise RobotModelError(f"{robot.name}: no frame '{frame}' for the IMU" + (f"; {close}" if close else "")
                              + (f"; IMU-like frames: {near}" if near else ""))
    model, data = robot.model, robot.data
    fid = model.getFrameId(frame)
    on_base = model.frames[fid].parentJoint == 1
    if IMU_KEY not in traj.extras:
        raise DataError(f"an IMU frame was given ('{frame}') but the log has no '{IMU_KEY}'", traj.source)
    imu = np.asarray(traj.extras[IMU_KEY], float)
    n = len(traj)
    if imu.shape != (n, 3):
        raise ShapeMismatchError(f"'{IMU_KEY}' has shape {imu.shape}; expected ({n}, 3)", traj.source)
    if traj.a is None and not on_base:
        raise DataError(f"the IMU frame '{frame}' is not on the base body: joint accelerations 'a' are needed",
                        traj.source)
    perm = robot.joint_order(traj.joint_names, traj.source)
    Q = robot.full_configuration(traj.q[:, perm], traj.base_q)
    V = robot.full_velocity(traj.v[:, perm], traj.base_v)
    A = robot.full_velocity(np.zeros((n, len(perm))) if traj.a is None else traj.a[:, perm])
    A[:, 3:6] = angular_acc
    gvec = np.array([0.0, 0.0, -g])
    lin = np.empty((n, 3))
    for i in range(n):
        pin.forwardKinematics(model, data, Q[i], V[i], A[i])
        Rs = pin.updateFramePlacement(model, data, fid).rotation
        acc0 = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear
        lin[i] = data.oMi[1].rotation.T @ (Rs @ imu[i] + gvec - acc0)
    return np.hstack([lin, angular_acc])


def base_acceleration(
    traj: Trajectory,
    window: int | None = None,
    polyorder: int = 3,
    use_imu: bool = True,
    imu_offset: np.ndarray | None = None,
    *,
    imu_rotation: np.ndarray | None = None,
    robot=None,
    imu_frame: str | None = None,
) -> Trajectory:
    """``traj`` with ``base_a`` filled: ω̇ by a Savitzky–Golay derivative of the gyro
    (``base_v[:, 3:]``); the linear part from ``extras["imu_acc"]`` when present and
    ``use_imu`` (:func:`imu_base_acceleration` with ``imu_offset``/``imu_rotation``, or
    :func:`imu_frame_base_acceleration` when ``robot`` and ``imu_frame`` name the sensor's
    model frame), else by differentiating ``base_v[:, :3]``."""
    if traj.base_q is None or traj.base_v is None:
        raise DataError("base acceleration needs base_q and base_v (a floating-base log)", traj.source)
    dt = uniform_dt(traj, "base_acceleration")
    if window is None:  # the package's one default derivative window (0.2 s)
        window = default_savgol_window(1.0 / dt)
    sg = SavitzkyGolay(window=window, polyorder=polyorder, dt=dt)
    dv = sg.apply(traj.base_v, deriv=1)
    has_imu = use_imu and IMU_KEY in traj.extras
    if has_imu:
        imu = np.asarray(traj.extras[IMU_KEY], float)
        bad = np.argwhere(~np.isfinite(imu))
        if bad.size:
            raise DataError(f"'{IMU_KEY}' has a non-finite value at sample {bad[0][0]}", traj.source)
        if imu_frame is not None:
            if robot is None:
                raise RobotModelError(f"{setting('imu_frame')} needs the robot model ({setting('robot')})")
            base_a = imu_frame_base_acceleration(robot, traj, imu_frame, dv[:, 3:])
        else:
            base_a = imu_base_acceleration(traj.base_q, traj.base_v, imu, dv[:, 3:], imu_offset, rotation=imu_rotation)
    elif use_imu and imu_frame is not None:
        raise DataError(f"an IMU frame was given ('{imu_frame}') but the log has no '{IMU_KEY}'", traj.source)
    else:
        base_a = dv
    note = (f"base_a: {'linear from imu_acc' + (f' at frame {imu_frame}' if imu_frame else '') + ', ' if has_imu else ''}savgol(window={window}, polyorder={polyorder}) "
            f"derivative of base_v{'[3:]' if has_imu else ''}")
    return traj.with_(base_a=base_a, units=note_processing(traj, note))

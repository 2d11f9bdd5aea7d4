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
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError, ShapeMismatchError
from .filtering import SavitzkyGolay, _note, _uniform_dt
from .trajectory import Trajectory

__all__ = ["IMU_KEY", "base_acceleration", "gravity_in_base", "imu_base_acceleration"]

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
) -> np.ndarray:
    """(N, 6) LOCAL base acceleration from the accelerometer's specific force (module docstring)."""
    base_v, imu_acc, angular_acc = (np.asarray(a, float) for a in (base_v, imu_acc, angular_acc))
    n = base_v.shape[0]
    for name, arr, cols in (("base_q", np.asarray(base_q), 7), ("base_v", base_v, 6), (IMU_KEY, imu_acc, 3),
                            ("angular_acc", angular_acc, 3)):
        if arr.shape != (n, cols):
            raise ShapeMismatchError(f"{name} has shape {arr.shape}; expected ({n}, {cols})")
    v, w = base_v[:, :3], base_v[:, 3:]
    lin = imu_acc + gravity_in_base(base_q, g) - np.cross(w, v)
    if offset is not None:
        r = np.broadcast_to(np.asarray(offset, float), (n, 3))
        lin = lin - np.cross(angular_acc, r) - np.cross(w, np.cross(w, r))
    return np.hstack([lin, angular_acc])


def base_acceleration(
    traj: Trajectory,
    window: int = 9,
    polyorder: int = 3,
    use_imu: bool = True,
    imu_offset: np.ndarray | None = None,
) -> Trajectory:
    """``traj`` with ``base_a`` filled: ω̇ by a Savitzky–Golay derivative of the gyro
    (``base_v[:, 3:]``); the linear part from ``extras["imu_acc"]`` when present and
    ``use_imu`` (:func:`imu_base_acceleration`), else by differentiating ``base_v[:, :3]``."""
    if traj.base_q is None or traj.base_v is None:
        raise DataError("base acceleration needs base_q and base_v (a floating-base log)", traj.source)
    dt = _uniform_dt(traj, "base_acceleration")
    sg = SavitzkyGolay(window=window, polyorder=polyorder, dt=dt)
    dv = sg.apply(traj.base_v, deriv=1)
    has_imu = use_imu and IMU_KEY in traj.extras
    if has_imu:
        imu = np.asarray(traj.extras[IMU_KEY], float)
        bad = np.argwhere(~np.isfinite(imu))
        if bad.size:
            raise DataError(f"'{IMU_KEY}' has a non-finite value at sample {bad[0][0]}", traj.source)
        base_a = imu_base_acceleration(traj.base_q, traj.base_v, imu, dv[:, 3:], imu_offset)
    else:
        base_a = dv
    note = (f"base_a: {'linear from imu_acc, ' if has_imu else ''}savgol(window={window}, polyorder={polyorder}) "
            f"derivative of base_v{'[3:]' if has_imu else ''}")
    return traj.with_(base_a=base_a, units=_note(traj, note))

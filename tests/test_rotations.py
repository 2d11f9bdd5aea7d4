"""Rotation helpers of the quadruped simulation against Pinocchio oracles (they use SciPy and
Pinocchio; these tests pin the conventions: quaternions [x y z w], R = Rz(yaw) Ry(pitch) Rx(roll),
ω in the world frame)."""

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from sensorless_studies.simulation.mujoco_scene import quat_to_matrix
from sensorless_studies.simulation.quadruped_control import world_angular_velocity
from sensorless_studies.simulation.quadruped_log import noisy_orientation

RNG = np.random.default_rng(7)


def _unit_quats(n):
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_quat_to_matrix_matches_pinocchio():
    q = _unit_quats(50)
    R = quat_to_matrix(q)
    for k in range(len(q)):
        np.testing.assert_allclose(R[k], pin.Quaternion(q[k]).toRotationMatrix(), atol=1e-12)
    assert quat_to_matrix(q.reshape(5, 10, 4)).shape == (5, 10, 3, 3)


def test_rpy_convention_matches_pinocchio():
    rpy = RNG.uniform(-1.5, 1.5, size=(30, 3))
    R = Rotation.from_euler("xyz", rpy).as_matrix()  # what quadruped_control.references uses
    for k in range(len(rpy)):
        np.testing.assert_allclose(R[k], pin.rpy.rpyToMatrix(*rpy[k]), atol=1e-12)


def test_world_angular_velocity_is_the_derivative_of_the_rotation():
    """ω_world = vee(Ṙ Rᵀ), by central differences of R(rpy(t)) along a smooth path."""
    t = np.linspace(0.0, 1.0, 201)
    dt = t[1] - t[0]
    rpy = np.stack([0.3 * np.sin(2 * t), 0.4 * np.cos(3 * t), 1.2 * t], axis=1)
    drpy = np.stack([0.6 * np.cos(2 * t), -1.2 * np.sin(3 * t), 1.2 + 0 * t], axis=1)
    w = world_angular_velocity(rpy, drpy)
    R = Rotation.from_euler("xyz", rpy).as_matrix()
    for k in range(1, len(t) - 1, 20):
        w_fd = pin.log3(R[k + 1] @ R[k - 1].T) / (2 * dt)
        np.testing.assert_allclose(w[k], w_fd, atol=1e-4)


def test_noisy_orientation_is_right_multiplied_exp_of_the_noise():
    q = _unit_quats(20)
    sigma = 0.05
    out = noisy_orientation(q, sigma, np.random.default_rng(3))
    dtheta = np.random.default_rng(3).normal(size=(20, 3)) * sigma
    for k in range(len(q)):
        R_expected = pin.Quaternion(q[k]).toRotationMatrix() @ pin.exp3(dtheta[k])
        np.testing.assert_allclose(pin.Quaternion(out[k]).toRotationMatrix(), R_expected, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-15)

"""``sensorless.testing``: synthetic logs with known ground truth, used by the tests as oracles."""

import numpy as np

from sensorless.excitation import random_fourier
from sensorless.parameters import is_physically_consistent
from sensorless.regressor import ModelStructure
from sensorless.testing import perturbed_truth, synthetic_trajectory


def test_perturbed_truth_is_consistent_seeded_and_differs_from_the_nominal(ur5):
    a, b, c = (perturbed_truth(ur5, rng=s) for s in (7, 7, 8))
    pa = a.parameters()
    assert is_physically_consistent(a.robot.inertial_parameters())
    assert np.array_equal(pa, b.parameters())  # same seed, same truth
    assert not np.allclose(pa, c.parameters())  # another seed, another truth
    assert not np.allclose(a.robot.inertial_parameters(), ur5.inertial_parameters())
    assert np.all(a.fv > 0) and np.all(a.fc > 0) and np.all(a.armature > 0)


def test_noise_free_torques_equal_regressor_times_true_parameters(ur5):
    """The synthetic log's τ is Y(q, v, v̇) π plus the joint terms, exactly (an independent oracle path)."""
    truth = perturbed_truth(ur5, rng=1)
    traj = synthetic_trajectory(truth, random_fourier(ur5, rng=2).sample(80, 4.0), noise_std=0.0)
    s = ModelStructure(truth.robot)
    r = truth.robot
    W = s.evaluate(r.full_configuration(traj.q), r.full_velocity(traj.v), r.full_velocity(traj.a))
    cols = [r.joint_names.index(j) for j in r.actuated_joints]
    np.testing.assert_allclose(W @ truth.parameters(s.joint_terms), traj.tau[:, cols], atol=1e-9, rtol=0)


def test_noise_is_seeded_and_has_the_requested_scale(ur5):
    truth = perturbed_truth(ur5, rng=1)
    motion = random_fourier(ur5, rng=2).sample(4000, 8.0)
    clean = synthetic_trajectory(truth, motion, noise_std=0.0).tau
    x, y = (synthetic_trajectory(truth, motion, noise_std=0.3, rng=5).tau for _ in range(2))
    assert np.array_equal(x, y)
    assert abs(np.std(x - clean) / 0.3 - 1) < 0.05

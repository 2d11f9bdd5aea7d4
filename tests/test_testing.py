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


def test_real_artefacts_quantize_round_hold_deflect_and_scale(ur5):
    """Each artefact does what a lab's recording does, and only on the joints named."""
    from sensorless.testing import RealArtefacts, one_joint_at_a_time, rest_segments, with_real_artefacts

    truth = perturbed_truth(ur5, rng=3)
    t = np.arange(0, 12, 0.002)
    q, v, a = one_joint_at_a_time(t, np.zeros(ur5.n_actuated) + 0.3)
    clean = synthetic_trajectory(truth, random_fourier(ur5, rng=2).sample(len(t), 500.0).with_(t=t, q=q, v=v, a=a))
    # a single-joint protocol: joint k moves only in its share, ending where it began, at rest
    moving = np.abs(v) > 1e-9
    assert moving.any(axis=0).all() and moving.sum(axis=1).max() == 1
    np.testing.assert_allclose(q[-1], 0.3, atol=1e-9)
    art = RealArtefacts(q_step=1e-4, decimals=4, gain_error=0.1, holding=0.5, stiffness=5e4)
    real = with_real_artefacts(clean, art, rng=0)
    assert real.a is None and real.provenance["artefacts"]["gain_error"] == 0.1
    np.testing.assert_allclose(real.tau, 1.1 * (clean.tau + (real.tau / 1.1 - clean.tau)))
    steps = real.q / 1e-4
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)  # quantized
    assert np.array_equal(real.v, np.round(real.v, 4))  # rounded to 4 decimals
    # holding torque: constant within each rest segment, different between segments, bounded by 0.5 (×1.1)
    k = 0
    held = real.tau[:, k] / 1.1 - clean.tau[:, k]
    segs = rest_segments(np.abs(clean.v[:, k]) < 1e-3)
    levels = [held[s] for s in segs]
    assert all(np.ptp(lv) < 1e-9 for lv in levels) and np.ptp([lv[0] for lv in levels]) > 0
    assert np.all(np.abs(held) <= 0.5 + 1e-12)
    # deflection: the encoder sees q + τ/k before quantization
    assert np.max(np.abs(real.q - (clean.q + real.tau / 1.1 / 5e4))) <= 0.5e-4 + 1e-12
    only = with_real_artefacts(clean, art, rng=0, joints=[ur5.joint_names[1]])
    assert np.array_equal(only.q[:, 0], clean.q[:, 0]) and not np.array_equal(only.q[:, 1], clean.q[:, 1])

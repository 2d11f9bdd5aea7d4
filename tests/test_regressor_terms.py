"""Oracle tests: regressor · parameters equals an independent RNEA computation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.identification.base import random_states
from sensorless.regressor import ModelStructure, NormalEquations, compress
from sensorless.testing import perturbed_truth


def _rnea_reference(robot, truth, Q, V, A):
    """τ on all nv rows: Pinocchio RNEA with armature set in the model + joint terms on actuated rows."""
    model = truth.robot.model.copy()
    model.armature[:] = 0.0
    act = robot.actuated_v_indices
    model.armature[act] = truth.armature
    data = model.createData()
    tau = np.array([pin.rnea(model, data, Q[i], V[i], A[i]) for i in range(len(Q))])
    v = V[:, act]
    tau[:, act] += truth.fv * v + truth.fc * np.sign(v) + truth.offset
    return tau


@pytest.mark.parametrize("name", ["panda", "ur5", "solo12", "kuka"])
def test_regressor_times_parameters_equals_rnea(name, request, rng):
    robot = request.getfixturevalue(name)
    truth = perturbed_truth(robot, rng=3)
    structure = ModelStructure(truth.robot)
    Q, V, A = random_states(structure, 50, rng)
    W = structure.evaluate(Q, V, A)
    tau = _rnea_reference(robot, truth, Q, V, A)
    rows = np.arange(robot.nv) if structure.rows == "all" else robot.actuated_v_indices
    pred = W @ truth.parameters(structure.joint_terms)
    assert structure.rows == ("all" if robot.floating_base else "actuated")
    np.testing.assert_allclose(pred, tau[:, rows], atol=1e-9, rtol=0)


def test_block_compression_equals_dense_normal_equations(solo12, rng):
    """The sparse block fold (add_blocks) equals WᵀW of the assembled regressor."""
    structure = ModelStructure(solo12)
    Q, V, A = random_states(structure, 40, rng)
    W = structure.evaluate(Q, V, A)
    y = rng.normal(size=(40, structure.n_rows))
    dense = NormalEquations.zeros(structure.n_rows, structure.n_params)
    dense.add(W, y)
    blocks = NormalEquations.zeros(structure.n_rows, structure.n_params)
    blocks.add_blocks(structure.body_regressor(Q, V, A), structure.joint_features(V, A), structure.actuated_rows, y)
    np.testing.assert_allclose(blocks.A, dense.A, atol=1e-9)
    np.testing.assert_allclose(blocks.b, dense.b, atol=1e-9)
    np.testing.assert_allclose(blocks.c, dense.c)


def test_compression_is_chunk_independent_and_gives_residuals(panda):
    """Chunked compression = one-shot; per-row residuals from the sums equal direct ones."""
    from sensorless.excitation import random_fourier
    from sensorless.testing import synthetic_trajectory

    truth = perturbed_truth(panda, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(100, 6.0), noise_std=0.1, rng=2)
    s = ModelStructure(panda)
    a = compress(s, traj, chunk=37)
    b = compress(s, list(traj.chunks(250)), chunk=4096)
    np.testing.assert_allclose(a.A, b.A, rtol=1e-12, atol=1e-9)
    params = truth.parameters(s.joint_terms)
    keep = s.fit_mask(s.state(traj)[1])  # the samples next to a velocity reversal are not in the fit
    assert 0.9 < keep.mean() < 1.0
    direct = (keep * (s.torques(params, traj) - s.target(traj)) ** 2).sum(axis=0)
    np.testing.assert_allclose(a.residual_ss(params), direct, rtol=1e-6)
    np.testing.assert_allclose(a.y_max - a.y_min, np.ptp(s.target(traj), axis=0))


def test_joint_terms_subset_and_labels(panda):
    s = ModelStructure(panda, joint_terms=("fv", "offset"))
    assert s.n_params == 70 + 2 * 7
    assert s.labels[s.joint_term_index("panda_joint3", "offset")] == "panda_joint3.offset"
    assert s.labels[0] == "panda_joint1.m"

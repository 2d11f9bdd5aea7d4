"""The candidate friction columns of the law search (StribeckCandidates.candidate_columns): the blocked
NumPy route is the element-wise law (tanh(v/w), (1 − e^{−(v/vs)²}) sgn v, 0 at rest and on joints not
searched, sgn v for a zero width) to the last bit, and the C++ kernel (which skips the saturated libm
calls and uses exp away from 0) agrees with it to rounding on every branch: saturated, the exp forms,
near 0 and exactly 0."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.identification.stribeck import FEATURE_BLOCK, StribeckCandidates
from sensorless.regressor import ModelStructure, native
from sensorless.regressor.friction_columns import stribeck_decay
from sensorless.robot import load_robot

TERMS = ("fv", "fc", "stribeck", "offset", "armature")


@pytest.fixture(scope="module")
def cand():
    robot = load_robot("ur5")
    joints = list(robot.actuated_joints)
    eps = dict(zip(joints, [0.01, 0.0, 0.02, 0.005, 0.01, 0.03]))  # joint 2: ε = 0 (the sign function)
    s = ModelStructure(robot, joint_terms=TERMS, coulomb_smoothing=eps, stribeck_velocity=0.05,
                       rest_velocity=dict(zip(joints, [1e-3] * 6)))
    grid = {j: np.geomspace(0.01, 0.4, 7) for j in joints[:4]}  # joints 5, 6: not searched
    widths = {j: [1e-9, 1e-4, 0.02, 0.3] for j in joints[:3]}
    return StribeckCandidates(s, grid, widths)


def _velocities(cand, n=3 * FEATURE_BLOCK + 17, seed=0):
    """Velocities across every branch: |v/w| and (v/vs)² around the saturation (20, 40) and the exp
    forms' thresholds (0.5, ln 2), tiny, within the rest velocity, and exactly 0."""
    rng = np.random.default_rng(seed)
    J = cand.widths.shape[0]
    k = rng.integers(0, 3, (n, J))
    ref = np.where(k == 0, cand.widths[np.arange(J), rng.integers(0, cand.widths.shape[1], J)][None, :],
                   cand.grid[np.arange(J), rng.integers(0, cand.grid.shape[1], J)][None, :])
    ratio = rng.choice([0.0, 1e-7, 0.3, 0.5, 0.6931471805599453, 0.9, 2.0, 6.3, 19.99, 20.0, 20.01, 40.0, 1e3],
                       (n, J)) * rng.uniform(0.97, 1.03, (n, J))
    v = ratio * ref * rng.choice([-1.0, 1.0], (n, J))
    v[rng.random((n, J)) < 0.05] = 5e-4  # at rest (|v| ≤ δ = 1e-3)
    return v


def _law(cand, v, sgn):
    """The columns as the element-wise law (friction_columns): the reference."""
    on = cand.searched[None, :, None]
    w = cand.widths[None]
    T = np.where(w > 0, np.tanh(v[:, :, None] / np.where(w > 0, w, 1.0)), np.sign(v)[:, :, None])
    T = T * ((sgn != 0)[:, :, None] * on)
    D = stribeck_decay(v[:, :, None], cand.grid[None], sgn[:, :, None] * on)
    return np.concatenate([T, D], axis=2)


def test_numpy_route_is_the_law_to_the_last_bit(cand):
    v = _velocities(cand)
    sgn = cand.structure.sliding_sign(v)
    out = np.full((len(v), v.shape[1], cand.n_terms - len(TERMS)), np.nan)
    cand.candidate_columns(v, sgn, out, native=False)
    ref = _law(cand, v, sgn)
    assert np.array_equal(out, ref)
    assert (ref[:, 1, : cand.widths.shape[1]] == np.sign(v[:, 1:2]) * (sgn[:, 1:2] != 0))[:, 0].all()
    assert not ref[:, 4:].any()  # joints not searched: zero columns


@pytest.mark.skipif(not native.available(), reason="the C++ kernel is not built")
def test_kernel_equals_the_numpy_route(cand):
    v = _velocities(cand, seed=1)
    sgn = cand.structure.sliding_sign(v)
    J, G = v.shape[1], cand.n_terms - len(TERMS)
    ref = np.empty((len(v), J, G))
    cand.candidate_columns(v, sgn, ref, native=False)
    wide = np.full((J, len(v), G + 5), np.nan)  # a strided view, as the streamed pass gives it
    out = wide[:, :, 2 : 2 + G].transpose(1, 0, 2)
    cand.candidate_columns(v, sgn, out, native=True)
    assert np.all(np.isfinite(out)) and np.isnan(wide[:, :, :2]).all() and np.isnan(wide[:, :, 2 + G :]).all()
    assert np.abs(out - ref).max() <= 4e-16  # |columns| ≤ 1: a few ulp
    assert np.array_equal(out == 0, ref == 0)  # at rest, not searched, v = 0: exactly 0 in both


def test_joint_features_into_a_view_equal_the_fresh_array(cand):
    v = _velocities(cand, n=300, seed=2)
    V = np.zeros((len(v), cand.robot.nv))
    V[:, cand.robot.term_v_indices] = v
    A = np.random.default_rng(3).standard_normal(V.shape)
    F = cand.joint_features(V, A)
    buf = np.zeros((len(v), 6, cand.n_terms + 4))
    got = cand.joint_features(V, A, None, out=buf[:, :, 4:])
    assert got.base is buf and np.array_equal(buf[:, :, 4:], F) and not buf[:, :, :4].any()
    assert np.array_equal(F[:, :, : len(TERMS)], cand.structure.joint_features(V, A))

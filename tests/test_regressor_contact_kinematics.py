"""The batched contact projector P = I − Jc⁺Jc against a per-sample ``numpy.linalg.pinv`` loop (1e-10),
on both routes (the C++ kernel when built, and NumPy), with rank-deficient contact Jacobians of a real
robot: a foot listed twice, a 6-D foot with its own point contact, rows below pinv's cut-off, a
stretched leg, flight (zero rows), and a chunk whose batched Cholesky fails (exactly singular G)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.regressor import contact_kinematics, native
from sensorless.regressor.contact_kinematics import contact_jacobians, null_space_projector

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
RCOND = 1e-7  # ContactStructure's default


def _pinv_loop(J, rcond):
    nv = J.shape[2]
    return np.array([np.eye(nv) - np.linalg.pinv(Ji, rcond=rcond) @ Ji for Ji in J])


@pytest.fixture(params=["kernel", "numpy"])
def route(request, monkeypatch):
    if request.param == "kernel":
        if native.contact_projector() is None:
            pytest.skip("C++ kernel not built (python -m sensorless.regressor.native_build)")
    else:
        monkeypatch.setattr(native, "contact_projector", lambda: None)
    return request.param


def _solo12_jacobians(robot, n, rng):
    m = robot.model
    Q = np.array([pin.integrate(m, pin.neutral(m), rng.normal(size=m.nv)) for _ in range(n)])
    Q[::4, robot.q_index("FL_KFE")] = 0.0  # a stretched leg (singular leg Jacobian)
    fids = [robot.frame_id(f) for f in FEET]
    active = rng.random((n, 4)) < 0.7
    active[::9] = False  # flight: all rows zero
    return Q, fids, active


def test_projector_equals_the_pinv_loop_on_dependent_and_ill_conditioned_contacts(solo12, route):
    rng = np.random.default_rng(5)
    Q, fids, active = _solo12_jacobians(solo12, 400, rng)
    cases = {
        "four feet, inactive rows zero": contact_jacobians(solo12, fids, [3] * 4, Q, active),
        "a foot listed twice": contact_jacobians(solo12, fids + fids[:1], [3] * 5, Q, np.hstack([active, active[:, :1]])),
        "6-D foot and its point contact": contact_jacobians(solo12, fids[:2] + fids[:1], [6, 3, 3], Q,
                                                            np.ones((len(Q), 3), bool)),
    }
    near = contact_jacobians(solo12, fids + fids[:1], [3] * 5, Q, np.ones((len(Q), 5), bool))
    near[:, 12:] += 1e-12 * rng.normal(size=near[:, 12:].shape)  # σ_min ≈ 1e-12 σ_max: pinv drops it
    cases["rows below the cut-off"] = near
    above = contact_jacobians(solo12, fids + fids[:1], [3] * 5, Q, np.ones((len(Q), 5), bool))
    above[:, 12:] += 1e-4 * rng.normal(size=above[:, 12:].shape)  # σ_min ≈ 1e-4 σ_max: pinv keeps it
    cases["rows above the cut-off"] = above
    for name, J in cases.items():
        P = null_space_projector(J, RCOND)
        ref = _pinv_loop(J, RCOND)
        assert np.abs(P - ref).max() < 1e-10, name
        if name != "rows below the cut-off":  # there P keeps the dropped direction: J P ≈ 1e-12
            assert np.abs(np.matmul(J, P)).max() < 1e-10 * np.abs(J).max(), name
    # the duplicate and the near-duplicate rows do not change the projector of the four feet
    four = contact_jacobians(solo12, fids, [3] * 4, Q, np.ones((len(Q), 4), bool))
    assert np.abs(null_space_projector(near, RCOND) - null_space_projector(four, RCOND)).max() < 1e-10


def test_random_stacks_with_zero_dependent_and_excess_rows_match_pinv(route):
    rng = np.random.default_rng(6)
    nv = 18
    for m in (3, 12, 18, 21):  # 21 > nv rows: G singular, every sample by the SVD
        J = rng.normal(size=(300, m, nv)) * rng.uniform(0.01, 100, size=(300, 1, 1))
        J[::5, -1] = J[::5, 0]  # dependent rows
        J[1::7] = 0.0  # flight
        J[2::11, : m // 2] = 0.0  # inactive contacts
        for rcond in (1e-7, 1e-10):
            np.testing.assert_allclose(null_space_projector(J, rcond), _pinv_loop(J, rcond), rtol=0, atol=1e-10)
        np.testing.assert_allclose(null_space_projector(J, RCOND, method="svd"), _pinv_loop(J, RCOND), rtol=0, atol=1e-10)


def test_a_chunk_whose_batched_cholesky_fails_keeps_its_good_samples_on_the_fast_route(monkeypatch):
    """An exactly singular G (duplicated integer rows) makes NumPy's batched Cholesky raise for the whole
    chunk: the chunk is certified on a damped factor, its good samples refactored, only the bad one goes to the SVD."""
    monkeypatch.setattr(native, "contact_projector", lambda: None)
    rng = np.random.default_rng(7)
    J = rng.normal(size=(64, 6, 18))
    J[10] = 0.0
    J[10, 0, 0] = J[10, 1, 0] = 1.0  # G = [[1, 1], [1, 1], ...]: pivot exactly 0
    G = np.matmul(J, J.transpose(0, 2, 1))
    G[10, 2:, 2:] = np.eye(4)  # (zero rows get unit pivots in the projector)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(G)
    by_svd = []
    real = contact_kinematics._svd_projector
    monkeypatch.setattr(contact_kinematics, "_svd_projector", lambda Js, r: by_svd.append(len(Js)) or real(Js, r))
    np.testing.assert_allclose(null_space_projector(J, RCOND), _pinv_loop(J, RCOND), rtol=0, atol=1e-10)
    assert by_svd == [1]


def test_non_finite_jacobians_give_nan_projectors_only_where_they_are(route):
    J = np.random.default_rng(8).normal(size=(20, 6, 18))
    J[3, 2, 5] = np.nan
    P = null_space_projector(J, RCOND)
    assert np.isnan(P[3]).all() and np.isfinite(np.delete(P, 3, axis=0)).all()


@pytest.mark.skipif(not native.available(), reason="C++ kernel not built (pure-Python path)")
def test_the_built_kernel_has_the_projector():
    assert native.contact_projector() is not None, "stale kernel: run `python -m sensorless.regressor.native_build`"

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import PhysicalConsistencyError, SensorlessError
from sensorless.parameters import (
    PARAMETER_NAMES,
    TERM_NAMES,
    JointTerms,
    check_physical_consistency,
    com_frame,
    from_com_frame,
    from_log_cholesky,
    from_pseudo_inertia,
    from_urdf_inertial,
    is_physically_consistent,
    log_cholesky,
    parameter_labels,
    pseudo_inertia,
    pseudo_inertia_basis,
    urdf_inertial,
)
from sensorless.robot import load_robot

KUKA = Path("/work/shared/realdata/kuka_lwr4_flobaroid/model/kuka_lwr4.urdf")


def random_bodies(n: int, consistent: bool = False) -> np.ndarray:
    """pin.Inertia.Random() bodies; with consistent=True keep only PD pseudo-inertias."""
    out = []
    while len(out) < n:
        I = pin.Inertia.Random()
        if not consistent or np.linalg.eigvalsh(I.toPseudoInertia().toMatrix())[0] > 1e-6:
            out.append(I.toDynamicParameters())
    return np.array(out)


@pytest.fixture(autouse=True)
def _seed():
    np.random.seed(0)
    pin.seed(0)


def test_labels():
    assert PARAMETER_NAMES == ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
    labels = parameter_labels(["a", "b"])
    assert len(labels) == 20 and labels[0] == "a.m" and labels[19] == "b.Izz"


def test_pseudo_inertia_matches_pinocchio():
    P = random_bodies(20)
    J = pseudo_inertia(P)
    for k, pi in enumerate(P):
        np.testing.assert_allclose(J[k], pin.PseudoInertia.FromDynamicParameters(pi).toMatrix(), atol=1e-14)
        np.testing.assert_allclose(
            from_pseudo_inertia(J[k]), pin.PseudoInertia.FromMatrix(J[k]).toDynamicParameters(), atol=1e-14
        )
    # vectorised over arbitrary leading dims and round trip
    P3 = P.reshape(4, 5, 10)
    assert pseudo_inertia(P3).shape == (4, 5, 4, 4)
    np.testing.assert_allclose(from_pseudo_inertia(pseudo_inertia(P3)), P3, atol=1e-14)


def test_pseudo_inertia_basis():
    A = pseudo_inertia_basis()
    assert A.shape == (10, 4, 4)
    P = random_bodies(5)
    np.testing.assert_allclose(np.einsum("ni,ijk->njk", P, A), pseudo_inertia(P), atol=1e-14)


def test_log_cholesky_matches_pinocchio():
    thetas = np.random.randn(20, 10)
    P = from_log_cholesky(thetas)
    for th, pi in zip(thetas, P):
        lc = pin.LogCholeskyParameters(th)
        np.testing.assert_allclose(pi, lc.toDynamicParameters(), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            pi, pin.Inertia.FromLogCholeskyParameters(lc).toDynamicParameters(), rtol=1e-12, atol=1e-12
        )
    np.testing.assert_allclose(log_cholesky(P), thetas, atol=1e-10)


def test_round_trips_on_consistent_bodies():
    P = random_bodies(30, consistent=True)
    th = log_cholesky(P)
    for t, pi in zip(th, P):
        np.testing.assert_allclose(pin.LogCholeskyParameters(t).toDynamicParameters(), pi, atol=1e-10)
    np.testing.assert_allclose(from_log_cholesky(th), P, atol=1e-10)
    np.testing.assert_allclose(from_pseudo_inertia(pseudo_inertia(P)), P, atol=1e-12)
    np.testing.assert_allclose(from_com_frame(*com_frame(P)), P, atol=1e-12)
    for pi in P:
        np.testing.assert_allclose(from_urdf_inertial(json.loads(json.dumps(urdf_inertial(pi)))), pi, atol=1e-10)
    assert is_physically_consistent(P)


def test_log_cholesky_rejects_non_pd():
    P = random_bodies(3, consistent=True)
    P[1, 0] = -1.0
    with pytest.raises(PhysicalConsistencyError, match=r"\(1,\)"):
        log_cholesky(P)
    with pytest.raises(ValueError):
        log_cholesky(P[1])
    assert issubclass(PhysicalConsistencyError, SensorlessError)


def test_com_frame_matches_pinocchio():
    P = random_bodies(10)
    m, c, I_c = com_frame(P)
    for k, pi in enumerate(P):
        ine = pin.Inertia.FromDynamicParameters(pi)
        assert m[k] == pytest.approx(ine.mass)
        np.testing.assert_allclose(c[k], ine.lever, atol=1e-12)
        np.testing.assert_allclose(I_c[k], ine.inertia, atol=1e-12)
        np.testing.assert_allclose(from_com_frame(ine.mass, ine.lever, ine.inertia), pi, atol=1e-12)
    # massless body: CoM reported as 0 and I_C = I
    m0, c0, I0 = com_frame(np.zeros(10))
    assert m0 == 0 and not c0.any() and not I0.any()


def test_urdf_inertial_with_link_frame():
    pi = random_bodies(1, consistent=True)[0]
    ine = pin.Inertia.FromDynamicParameters(pi)
    M = pin.SE3.Random()  # link frame in the joint frame
    d = urdf_inertial(pi, frame=M)
    expect = M.actInv(ine)  # same body seen from the link frame
    np.testing.assert_allclose(d["xyz"], expect.lever, atol=1e-12)
    np.testing.assert_allclose(d["ixx"], expect.inertia[0, 0], atol=1e-12)
    np.testing.assert_allclose(d["iyz"], expect.inertia[1, 2], atol=1e-12)
    np.testing.assert_allclose(from_urdf_inertial(d, frame=M), pi, atol=1e-12)
    # URDF with a principal-axes rpy on the inertial origin
    R = pin.rpy.rpyToMatrix(0.3, -0.2, 1.1)
    I_p = np.diag([1.0, 2.0, 2.5])
    d = {"mass": 2.0, "xyz": [0.1, 0.2, 0.3], "rpy": [0.3, -0.2, 1.1], "ixx": 1.0, "iyy": 2.0, "izz": 2.5}
    expect = pin.Inertia(2.0, np.array([0.1, 0.2, 0.3]), R @ I_p @ R.T).toDynamicParameters()
    np.testing.assert_allclose(from_urdf_inertial(d), expect, atol=1e-12)


def _body(mass, com, I_com):
    return from_com_frame(mass, np.asarray(com, float), np.asarray(I_com, float))


def test_consistency_negative_mass():
    pi = _body(-1.0, [0, 0, 0], np.diag([1.0, 1.0, 1.0]))
    (r,) = check_physical_consistency(pi, ["neg"])
    assert r.name == "neg" and r.mass == -1.0 and not r.consistent and r.min_eig_pseudo_inertia < 0
    assert not is_physically_consistent(pi)


def test_consistency_triangle_violation():
    # I_com positive definite but I1 + I2 < I3: no mass distribution produces it.
    pi = _body(1.0, [0.1, 0.0, 0.0], np.diag([1.0, 1.0, 3.0]))
    (r,) = check_physical_consistency(pi)
    assert np.all(r.principal_moments > 0)
    assert r.triangle_margin == pytest.approx(-1.0)
    assert not r.consistent and not is_physically_consistent(pi)


def test_consistency_indefinite_pseudo_inertia_despite_pd_com_inertia():
    # With m > 0, J >= 0  <=>  Sigma_C = 1/2 tr(I_C) 1 - I_C >= 0, whose eigenvalues are half the
    # triangle margins: an indefinite J with m > 0 and I_C > 0 is exactly a (rotated) triangle
    # violation. Build one in a non-principal frame and off the CoM.
    R = pin.rpy.rpyToMatrix(0.4, 0.7, -1.2)
    I_c = R @ np.diag([0.2, 0.5, 0.75]) @ R.T
    pi = _body(3.0, [0.05, -0.2, 0.1], I_c)
    (r,) = check_physical_consistency(pi)
    assert r.mass > 0 and np.linalg.eigvalsh(I_c).min() > 0
    assert r.min_eig_pseudo_inertia < 0 and not r.consistent
    # margin == 2 * min eig of Sigma_C
    S_c = 0.5 * np.trace(I_c) * np.eye(3) - I_c
    assert r.triangle_margin == pytest.approx(2 * np.linalg.eigvalsh(S_c)[0])
    assert r.triangle_margin == pytest.approx(-0.05)


def test_consistency_massless_zero_body_and_stacked_vector():
    P = np.concatenate([np.zeros(10), random_bodies(2, consistent=True).ravel()])
    reports = check_physical_consistency(P, ["root", "a", "b"])
    assert [r.name for r in reports] == ["root", "a", "b"]
    assert all(r.consistent for r in reports)
    assert is_physically_consistent(P)
    assert not is_physically_consistent(np.r_[P, [0.0, 1.0] + [0.0] * 8])  # m = 0 but h != 0


@pytest.mark.parametrize(
    "spec,kw",
    [
        ("panda", {"lock_joints": ["panda_finger_joint1", "panda_finger_joint2"]}),
        ("ur5", {}),
        ("solo12", {}),
        (str(KUKA), {}),
    ],
)
def test_real_bodies_are_consistent(spec, kw):
    if spec == str(KUKA) and not KUKA.exists():
        pytest.skip("KUKA LWR4 model not available")
    robot = load_robot(spec, **kw)
    pi = robot.inertial_parameters()
    reports = check_physical_consistency(pi, robot.body_names)
    assert all(r.consistent for r in reports), [r for r in reports if not r.consistent]
    assert all(r.triangle_margin > 0 for r in reports)
    assert is_physically_consistent(pi)
    np.testing.assert_allclose(from_log_cholesky(log_cholesky(pi.reshape(-1, 10))).ravel(), pi, atol=1e-10)


def test_joint_terms():
    jt = JointTerms(("j1", "j2"), fv=[0.1, 0.2], fc=np.array([1.0, 2.0]))
    assert TERM_NAMES == ("fv", "fc", "offset", "armature")
    np.testing.assert_array_equal(jt.armature, [0.0, 0.0])
    d = json.loads(json.dumps(jt.to_dict()))
    assert d["j2"] == {"fv": 0.2, "fc": 2.0, "offset": 0.0, "armature": 0.0}
    back = JointTerms.from_dict(d)
    assert back.joint_names == ("j1", "j2")
    for t in TERM_NAMES:
        np.testing.assert_array_equal(getattr(back, t), getattr(jt, t))
    assert JointTerms.from_dict({"a": {"fv": 1.0}}).fc.tolist() == [0.0]
    with pytest.raises(ValueError, match="fv"):
        JointTerms(("j1",), fv=[1.0, 2.0])
    with pytest.raises(ValueError, match="unknown term"):
        JointTerms.from_dict({"a": {"damping": 1.0}})

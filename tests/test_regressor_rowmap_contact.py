"""Contact row map: the residual W π − y equals P(q) (RNEA + Sᵀ Φ φ − Sᵀ τ) with P = I − Jc⁺Jc.

Oracle: RNEA of the floating-base model with random π, joint terms and torques placed by
hand, and P from NumPy's pinv of Pinocchio's stacked contact Jacobians of the active feet,
to 1e-9 on random states and random contact patterns. With measured wrenches the map is
the identity on the kept rows and Jcᵀ f is on the known side.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.data import Trajectory
from sensorless.regressor import ContactStructure
from sensorless.regressor.rowmap import ContactNullSpace, RowMap

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
TERMS = ("fv", "fc", "offset")


def _random_log(robot, rng, n=24):
    m = robot.model
    Q = np.array([pin.integrate(m, pin.neutral(m), rng.normal(size=m.nv)) for _ in range(n)])
    V, A = rng.normal(size=(n, m.nv)), rng.normal(size=(n, m.nv)) * 3
    flags = rng.random((n, 4)) < 0.6
    flags[0] = False  # one sample in flight: P = I
    qi = [robot.q_index(j) for j in robot.joint_names]
    vi = [robot.v_index(j) for j in robot.joint_names]
    tau = rng.normal(size=(n, robot.n_actuated)) * 2
    forces = rng.normal(size=(n, 4, 3)) * 10
    tr = Trajectory(t=np.arange(n) * 0.01, q=Q[:, qi], v=V[:, vi], a=A[:, vi], tau=tau, base_q=Q[:, :7],
                    base_v=V[:, :6], base_a=A[:, :6], joint_names=robot.joint_names,
                    extras={"contact": flags, "contact_forces": forces}, source="<random>")
    return tr, Q, V, A, flags, tau, forces


def _oracle_parts(robot, s, pi, Q, V, A, flags, tau):
    model = robot.model.copy()
    model.armature[:] = 0.0
    for k in range(robot.n_bodies):
        model.inertias[k + 1] = pin.Inertia.FromDynamicParameters(pi[10 * k : 10 * k + 10])
    data = model.createData()
    act = robot.actuated_v_indices
    full = np.array([pin.rnea(model, data, q, v, a) for q, v, a in zip(Q, V, A)])
    for k, (j, iv) in enumerate(zip(robot.actuated_joints, act)):
        fv, fc, o = (pi[s.joint_term_index(j, t)] for t in TERMS)
        full[:, iv] += fv * V[:, iv] + fc * np.sign(V[:, iv]) + o
    st_tau = np.zeros_like(full)
    st_tau[:, act] = tau
    fids = [robot.frame_id(f) for f in FEET]
    J = np.zeros((len(Q), 12, robot.nv))
    for i, q in enumerate(Q):
        pin.computeJointJacobians(model, data, q)
        for k, fid in enumerate(fids):
            if flags[i, k]:
                J[i, 3 * k : 3 * k + 3] = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
    return full, st_tau, J


def test_projected_residual_equals_null_space_projection_of_rnea_minus_torques(solo12):
    rng = np.random.default_rng(31)
    pin.seed(31)  # Inertia.Random draws from Pinocchio's own generator: the test must not depend on test order
    s = ContactStructure(solo12, joint_terms=TERMS, contact_frames=FEET)
    rm = s.row_map
    assert isinstance(rm, RowMap) and isinstance(rm, ContactNullSpace)
    assert rm.per_sample and not rm.selects_rows and rm.n_rows == solo12.nv
    tr, Q, V, A, flags, tau, _ = _random_log(solo12, rng)
    pi = np.concatenate([np.concatenate([pin.Inertia.Random().toDynamicParameters() for _ in solo12.body_names]),
                         rng.normal(size=s.n_params - s.n_body_params)])
    full, st_tau, J = _oracle_parts(solo12, s, pi, Q, V, A, flags, tau)
    P = np.array([np.eye(solo12.nv) - np.linalg.pinv(Ji) @ Ji for Ji in J])
    expected = np.einsum("nij,nj->ni", P, full - st_tau)
    scale = np.abs(full - st_tau).max()
    np.testing.assert_allclose(s.torques(pi, tr) - s.target(tr), expected, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(rm.apply(full - st_tau, Q, flags), expected, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(rm.apply(full[:1] - st_tau[:1], Q[:1], flags[:1]), (full - st_tau)[:1], atol=1e-12)
    # the projection really removes something on the samples in contact (P = I on the others)
    c = flags.any(axis=1)
    assert c.any() and np.linalg.norm(expected[c]) < 0.99 * np.linalg.norm((full - st_tau)[c])


def test_wrench_mode_rows_are_rnea_with_measured_wrenches_on_the_known_side(solo12):
    rng = np.random.default_rng(32)
    s = ContactStructure(solo12, joint_terms=TERMS, contact_frames=FEET, mode="wrench")
    tr, Q, V, A, flags, tau, forces = _random_log(solo12, rng)
    pi = np.concatenate([np.concatenate([pin.Inertia.Random().toDynamicParameters() for _ in solo12.body_names]),
                         rng.normal(size=s.n_params - s.n_body_params)])
    full, st_tau, J = _oracle_parts(solo12, s, pi, Q, V, A, flags, tau)
    jf = np.einsum("nmi,nm->ni", J, forces.reshape(len(tr), 12))
    scale = np.abs(full).max()
    np.testing.assert_allclose(s.torques(pi, tr), full, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(s.target(tr), st_tau + jf, rtol=0, atol=1e-9 * scale)
    np.testing.assert_array_equal(s.row_map.apply(full), full)


def test_null_space_map_needs_the_state(solo12):
    from sensorless.errors import DataError

    s = ContactStructure(solo12, contact_frames=FEET)
    with pytest.raises(DataError, match="configurations Q and the contact flags"):
        s.row_map.apply(np.zeros((2, solo12.nv)))

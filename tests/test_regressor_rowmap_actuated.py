"""Actuated row map: W π equals the selected rows of Pinocchio's RNEA plus the joint terms.

Oracle: RNEA of a model whose inertias are set from random π (armature 0, since the joint
terms carry it), rows Sᵀ-selected by hand, plus fv v + fc sgn v + o + Ia v̇ per actuated
joint computed directly, to 1e-9 on random states.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.regressor import ModelStructure
from sensorless.regressor.rowmap import ActuatedRows, RowMap
from sensorless.robot import Robot

TERMS = ("fv", "fc", "offset", "armature")


def _random_parameters(structure, rng):
    body = np.concatenate([pin.Inertia.Random().toDynamicParameters() for _ in structure.robot.body_names])
    return np.concatenate([body, rng.normal(size=structure.n_params - structure.n_body_params)])


def _rnea(robot, params, Q, V, A):
    """Full nv-row RNEA of ``robot`` with body parameters ``params[:10 n_bodies]``, no armature."""
    model = robot.model.copy()
    model.armature[:] = 0.0
    for k in range(robot.n_bodies):
        model.inertias[k + 1] = pin.Inertia.FromDynamicParameters(params[10 * k : 10 * k + 10])
    data = model.createData()
    return np.array([pin.rnea(model, data, q, v, a) for q, v, a in zip(Q, V, A)])


def _joint_terms(structure, params, V, A):
    """Σ fv v + fc sgn v + o + Ia v̇ on each actuated joint's velocity index (nv columns)."""
    r = structure.robot
    out = np.zeros(V.shape)
    for j, iv in zip(r.actuated_joints, r.actuated_v_indices):
        p = {t: params[structure.joint_term_index(j, t)] for t in TERMS}
        out[:, iv] = p["fv"] * V[:, iv] + p["fc"] * np.sign(V[:, iv]) + p["offset"] + p["armature"] * A[:, iv]
    return out


def _fixed_states(robot, rng, n=25):
    m = robot.model
    Q = np.array([pin.randomConfiguration(m) for _ in range(n)])
    return Q, rng.normal(size=(n, m.nv)), rng.normal(size=(n, m.nv)) * 3


@pytest.mark.parametrize("n_act", [None, 4])
def test_actuated_rows_equal_selected_rnea(panda, n_act):
    rng = np.random.default_rng(11)
    robot = panda if n_act is None else Robot(panda.model, name="under", actuated_joints=panda.joint_names[:n_act])
    s = ModelStructure(robot, joint_terms=TERMS)
    rm = s.row_map
    assert isinstance(rm, RowMap) and isinstance(rm, ActuatedRows)
    assert rm.selects_rows and not rm.per_sample
    assert rm.row_names == list(robot.actuated_joints) and rm.n_rows == s.n_rows == robot.n_actuated
    pi = _random_parameters(s, rng)
    Q, V, A = _fixed_states(robot, rng)
    full = _rnea(robot, pi, Q, V, A) + _joint_terms(s, pi, V, A)
    oracle = full @ robot.selection.T  # Sᵀ rows: S τ_full
    np.testing.assert_allclose(s.evaluate(Q, V, A) @ pi, oracle, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rm.apply(full), oracle, rtol=0, atol=0)
    np.testing.assert_array_equal(rm.matrix(robot.nv), robot.selection)


def test_all_rows_of_a_floating_base_equal_rnea_plus_actuated_terms(solo12):
    rng = np.random.default_rng(12)
    s = ModelStructure(solo12, joint_terms=TERMS, rows="all")
    rm = s.row_map
    assert rm.n_rows == solo12.nv and rm.selects_rows
    m = solo12.model
    n = 20
    Q = np.array([pin.integrate(m, pin.neutral(m), rng.normal(size=m.nv)) for _ in range(n)])
    V, A = rng.normal(size=(n, m.nv)), rng.normal(size=(n, m.nv)) * 3
    pi = _random_parameters(s, rng)
    oracle = _rnea(solo12, pi, Q, V, A) + _joint_terms(s, pi, V, A)
    np.testing.assert_allclose(s.evaluate(Q, V, A) @ pi, oracle, rtol=1e-9, atol=1e-9)
    assert np.abs(oracle[:, :6]).max() > 1e-3  # the unactuated base rows are really checked

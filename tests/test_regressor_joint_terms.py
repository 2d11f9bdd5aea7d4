"""The joint-term registry (sensorless.regressor.joint_terms): each term's column against a direct
computation of its formula, the registry's consistency, and the opt-in direction-dependent viscous term."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.errors import DataError
from sensorless.regressor import JOINT_TERMS, ModelStructure
from sensorless.regressor.joint_spec import PASSIVE_TERMS
from sensorless.regressor.joint_terms import REGISTRY, JointTerm, TermInputs, joint_term, terms_where

FLAGS = ("passive", "needs_motion", "acceleration", "nonnegative", "reversal", "stateful", "exported")


@pytest.fixture
def signals():
    rng = np.random.default_rng(7)
    v = rng.normal(0, 0.3, (200, 3))
    v[::9] = 0.0  # exact rest
    v[1::11] *= 1e-4  # within the rest velocity of joint 2
    a = rng.normal(size=v.shape)
    z = np.tanh(rng.normal(size=v.shape))
    eps, rest, vs = np.array([0.0, 0.02, 0.05]), np.array([0.0, 0.0, 1e-3]), np.array([0.05, 0.1, 0.2])
    return v, a, z, eps, rest, vs


def _direct(name, v, a, z, eps, rest, vs, law="blend"):
    """Each term's formula written out per sample and joint (scalar math, no shared helpers)."""
    out = np.empty_like(v)
    for i in range(v.shape[0]):
        for j in range(v.shape[1]):
            x, moving = v[i, j], abs(v[i, j]) > rest[j]
            T = (np.tanh(x / eps[j]) if eps[j] > 0 else float(np.sign(x))) if moving else 0.0
            s = float(np.sign(x)) if moving else 0.0
            out[i, j] = {
                "fv": x, "fc": T, "offset": 1.0, "armature": a[i, j], "fv_asym": abs(x),
                "presliding": np.nan if z is None else z[i, j],
                "stribeck": (np.exp(-(x / vs[j]) ** 2) * T if law == "product"
                             else T - (1.0 - np.exp(-(x / vs[j]) ** 2)) * s),
            }[name]
    return out


@pytest.mark.parametrize("name", JOINT_TERMS)
def test_each_column_equals_its_formula(name, signals):
    v, a, z, eps, rest, vs = signals
    col = joint_term(name).column(TermInputs(v, a, eps, rest, vs, "blend", z))
    np.testing.assert_allclose(col, _direct(name, v, a, z, eps, rest, vs), rtol=1e-12, atol=1e-15)


def test_product_law_stribeck_column(signals):
    v, a, z, eps, rest, vs = signals
    col = joint_term("stribeck").column(TermInputs(v, a, eps, rest, vs, "product", z))
    np.testing.assert_allclose(col, _direct("stribeck", v, a, z, eps, rest, vs, "product"), rtol=1e-12, atol=1e-15)


def test_registry_is_consistent():
    assert JOINT_TERMS == tuple(t.name for t in REGISTRY) and len(set(JOINT_TERMS)) == len(JOINT_TERMS)
    # the column order of models written before the registry is its prefix
    assert JOINT_TERMS[:6] == ("fv", "fc", "stribeck", "offset", "armature", "presliding")
    for t in REGISTRY:
        assert isinstance(t, JointTerm) and t.description
        assert all(isinstance(getattr(t, f), bool) for f in FLAGS), t.name
        with pytest.raises(Exception):
            t.name = "x"  # frozen
    assert PASSIVE_TERMS == terms_where("passive")
    assert terms_where("nonnegative") == ("fv", "fc", "armature")
    assert terms_where("reversal") == ("fc", "stribeck")
    assert terms_where("stateful") == ("presliding",) and not joint_term("presliding").exported


def test_structure_places_each_registered_column_on_its_joint_row(ur5, signals):
    """ModelStructure.evaluate puts term t of joint k at column n_block + k·n_terms + t, on joint k's row
    only: every registered memoryless term at once, against the direct formulas."""
    terms = tuple(t for t in JOINT_TERMS if not joint_term(t).stateful)
    s = ModelStructure(ur5, joint_terms=terms, coulomb_smoothing=0.02, stribeck_velocity=0.1)
    rng = np.random.default_rng(1)
    N, n = 40, ur5.nv
    Q, V, A = rng.normal(size=(N, ur5.nq)), rng.normal(0, 0.3, (N, n)), rng.normal(size=(N, n))
    W = s.evaluate(Q, V, A)
    nt = len(s.joint_terms)
    for k in range(n):
        block = W[:, :, s.n_block_params + k * nt: s.n_block_params + (k + 1) * nt]
        others = np.delete(block, k, axis=1)
        assert not others.any()
        for t_i, t in enumerate(s.joint_terms):
            want = _direct(t, V[:, [k]], A[:, [k]], None, np.array([0.02]), np.array([0.0]), np.array([0.1]))[:, 0]
            np.testing.assert_allclose(block[:, k, t_i], want, rtol=1e-12, atol=1e-15)


def test_presliding_column_needs_whole_log_states(signals):
    v, a, _, eps, rest, vs = signals
    with pytest.raises(DataError, match="history of q"):
        joint_term("presliding").column(TermInputs(v, a, eps, rest, vs))


def test_direction_dependent_viscous_friction_is_recovered(ur5):
    """fv± = fv ± fv_asym: simulated with different slopes per direction, identified (OLS) exactly enough."""
    from sensorless.data.trajectory import Trajectory
    from sensorless.identification import identify

    rng = np.random.default_rng(5)
    t = np.arange(0, 8, 0.005)
    n = ur5.n_actuated
    f, ph = rng.uniform(0.1, 0.4, (2, n)), rng.uniform(0, 2 * np.pi, (2, n))
    q = sum(0.5 * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(2))
    v = sum(0.5 * 2 * np.pi * f[k] * np.cos(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(2))
    a = sum(-0.5 * (2 * np.pi * f[k]) ** 2 * np.sin(2 * np.pi * f[k] * t[:, None] + ph[k]) for k in range(2))
    truth = ModelStructure(ur5, joint_terms=("fv", "fc", "offset", "fv_asym"))
    p = truth.prior()
    fv_plus, fv_minus = rng.uniform(1.0, 3.0, n), rng.uniform(0.2, 1.0, n)
    for k, j in enumerate(ur5.actuated_joints):
        p[truth.joint_term_index(j, "fv")] = (fv_plus[k] + fv_minus[k]) / 2
        p[truth.joint_term_index(j, "fv_asym")] = (fv_plus[k] - fv_minus[k]) / 2
        p[truth.joint_term_index(j, "fc")] = 1.0
    log = Trajectory(t=t, q=q, v=v, a=a, tau=np.zeros_like(q), joint_names=tuple(ur5.actuated_joints))
    log = log.with_(tau=truth.torques(p, log) + rng.normal(0, 0.01, q.shape))
    res = identify(ModelStructure(ur5, joint_terms=("fv", "fc", "offset", "fv_asym")), [log], method="ols")
    got = res.joint_terms()
    plus = np.array([got[j]["fv"] + got[j]["fv_asym"] for j in ur5.actuated_joints])
    minus = np.array([got[j]["fv"] - got[j]["fv_asym"] for j in ur5.actuated_joints])
    np.testing.assert_allclose(plus, fv_plus, rtol=0.02)
    np.testing.assert_allclose(minus, fv_minus, rtol=0.05)
    # opt-in: the default structure has no such column
    assert "fv_asym" not in ModelStructure(ur5).joint_terms

"""The friction state (sensorless.regressor.friction_state): oracles for the state update,
its rate independence, the play operator, streaming vs whole-log evaluation, and the law's checks."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.errors import ParameterError
from sensorless.regressor.friction_state import (
    FrictionLaw,
    FrictionStateIntegrator,
    dahl_state_blocks,
    dahl_states,
    play,
)


def _loop(qp, v, k, vs, s0=0.0):
    """Independent oracle: the exact update s_i = u_i + (s_{i-1} - u_i) exp(-k |dq_i|), one sample at a time."""
    out, s = [], np.full(1 + len(vs), float(s0))
    for i in range(len(qp)):
        dq = qp[i] - qp[i - 1] if i else 0.0
        if dq != 0:
            vbar = 0.5 * (v[i] + v[i - 1])
            u = np.sign(dq) * np.array([1.0] + [np.exp(-((vbar / x) ** 2)) for x in vs])
            s = u + (s - u) * np.exp(-k * abs(dq))
        out.append(s.copy())
    return np.array(out)


@pytest.fixture(scope="module")
def path():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.5e-3, 2e-3, 1500))
    q = 0.3 * np.sin(2.1 * t) + 0.05 * np.sin(7.3 * t)
    v = np.gradient(q, t)
    return t, q, v


def test_states_match_the_one_sample_update_across_blocks(path):
    _, q, v = path
    k, vs = np.array([3.0, 40.0, 900.0]), [0.05, 0.4]
    ref = np.stack([_loop(q, v, kk, vs) for kk in k], axis=1)
    assert np.allclose(dahl_states(q, v, k, vs), ref, atol=1e-12)
    blocks = np.concatenate([b for _, _, b in dahl_state_blocks(q, v, k, vs, block=37)])
    assert np.allclose(blocks, ref, atol=1e-12)


def test_state_after_a_reversal_follows_the_closed_form_whatever_the_steps():
    """From s = 1 (long motion up), moving down a distance d: s = -1 + 2 exp(-k d), for any sampling."""
    k = 200.0
    rng = np.random.default_rng(0)
    for n_down in (40, 400):
        up = np.linspace(0.0, 0.2, 300)
        down = 0.2 - np.sort(rng.uniform(0, 0.01, n_down))  # irregular steps
        q = np.concatenate([up, down])
        s = dahl_states(q, np.zeros_like(q), [k])[:, 0, 0]
        d = 0.2 - q[300:]
        assert np.allclose(s[300:], -1 + (1 + s[299]) * np.exp(-k * d), atol=1e-12)
        assert s[299] == pytest.approx(1.0, abs=1e-12)


def test_initial_state_adds_its_exponential_decay(path):
    """A state from s0 is the state from 0 plus s0 exp(-k S) (S the distance travelled): the fit's
    initial-state column is exact."""
    _, q, v = path
    k, s0 = 25.0, 0.7
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q)))])
    ref = _loop(q, v, k, [0.1], s0=s0)
    assert np.allclose(dahl_states(q, v, [k], [0.1])[:, 0, :] + s0 * np.exp(-k * travel)[:, None], ref, atol=1e-12)


def test_play_ignores_noise_within_its_width_and_follows_motion():
    rng = np.random.default_rng(1)
    noise = rng.uniform(-1e-4, 1e-4, 500)
    assert np.ptp(play(noise, 1e-4, start=0.0)) == 0.0
    ramp = np.linspace(0, 1, 200)
    p = play(ramp, 0.01)
    assert np.allclose(p[2:], ramp[2:] - 0.01)  # lags a monotone motion by the half-width
    assert np.array_equal(play(ramp, 0.0), ramp)


def test_streaming_integrator_equals_the_whole_log(path):
    t, q, v = path
    a = np.gradient(v, t)
    laws = [FrictionLaw("state", {"fc": 0.3, "stribeck": 0.1, "damping": 0.4, "fv": 0.05, "offset": 0.01,
                                  "inertia": 0.02}, vs=0.05, k=150.0, play=1e-5),
            FrictionLaw("static", {"fc": 0.2, "fv": 0.1}, eps=0.01)]
    full = np.column_stack([law.torque(q, v, a) for law in laws])
    it = FrictionStateIntegrator(laws)
    Q, V, A = np.column_stack([q, q]), np.column_stack([v, v]), np.column_stack([a, a])
    stream = np.array([it.step(Q[i], V[i], A[i]) for i in range(len(q))])
    assert np.allclose(stream, full, atol=1e-12)
    it.reset()
    assert np.allclose(it.step(Q[0], V[0], A[0]), full[0])


def test_state_law_tends_to_the_static_law_as_k_grows(path):
    t, q, v = path
    coef = {"fc": 0.3, "fv": 0.05}
    sharp = FrictionLaw("state", coef, k=1e7).torque(q, v)
    static = FrictionLaw("static", coef, eps=0.0).torque(q, v)
    moving = np.abs(v) > 0.05
    moving[0] = False  # the state starts at 0
    assert np.allclose(sharp[moving], static[moving], atol=1e-6)


def test_law_round_trips_and_refuses_bad_values():
    law = FrictionLaw("state", {"fc": 0.3, "stribeck": 0.1}, vs=0.02, k=400.0, play=1e-4)
    assert FrictionLaw.from_dict(law.to_dict()) == law
    assert law.presliding_distance == pytest.approx(1 / 400)
    for kwargs, match in [(dict(kind="dynamic", coef={"fc": 1.0}), "kind"),
                          (dict(kind="state", coef={"fc": 1.0}, k=0.0), "k > 0"),
                          (dict(kind="static", coef={"fc": 1.0, "damping": 1.0}), "damping"),
                          (dict(kind="static", coef={"fc": 1.0, "stribeck": 1.0}), "vs > 0"),
                          (dict(kind="static", coef={"fc": 1.0}, eps=float("nan")), "eps")]:
        with pytest.raises(ParameterError, match=match):
            FrictionLaw(**kwargs)

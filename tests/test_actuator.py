"""Actuator models and fits: recovery of known parameters on synthetic data, solver oracles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import norm

from sensorless.actuator import (
    MotorModel,
    asymmetric_least_squares,
    fit_asymmetric,
    fit_current_model,
    fit_least_squares,
    fit_piecewise_linear,
    fit_two_stage,
)
from sensorless.errors import ExcitationError, NonFiniteError, ShapeMismatchError

K_TAU = np.array([3e-4, 2e-4, 1.6e-4])
K_V = np.array([5e-3, 7e-3, 6e-3])
K_C = np.array([4e-4, 5e-4, 3e-4])


def _data(n=20000, noise=0.0, seed=0, coulomb=True):
    rng = np.random.default_rng(seed)
    tau = rng.uniform(-100, 100, (n, 3))
    dq = rng.normal(0, 0.8, (n, 3))
    y = K_TAU * tau + K_V * dq + (K_C * np.sign(dq) if coulomb else 0.0) + noise * rng.standard_normal((n, 3))
    return tau, dq, y


def test_least_squares_recovers_parameters():
    tau, dq, y = _data()
    m = fit_least_squares(tau, dq, y, coulomb=True)
    np.testing.assert_allclose(m.k_tau, K_TAU, rtol=1e-9)
    np.testing.assert_allclose(m.k_v, K_V, rtol=1e-9)
    np.testing.assert_allclose(m.k_c, K_C, rtol=1e-9)
    tau, dq, y = _data(noise=2e-4, seed=1)
    m = fit_least_squares(tau, dq, y, coulomb=True)
    np.testing.assert_allclose(m.k_tau, K_TAU, rtol=0.01)
    np.testing.assert_allclose(m.k_v, K_V, rtol=0.02)
    assert 0.4 < min(m.info["over_estimation_fraction"].values())  # symmetric fit: about half over


def test_asymmetric_exact_on_noiseless_data_and_matches_qp_oracle():
    tau, dq, y = _data(n=5000)
    m = fit_asymmetric(tau, dq, y, 100.0, coulomb=True)
    np.testing.assert_allclose(m.k_tau, K_TAU, rtol=1e-8)
    np.testing.assert_allclose(m.k_v, K_V, rtol=1e-8)
    # noisy data: compare the Newton solution with a conic solver (cvxpy + Clarabel)
    cp = pytest.importorskip("cvxpy")
    tau, dq, y = _data(n=3000, noise=3e-4, seed=3)
    X = np.column_stack([tau[:, 0], dq[:, 0], np.sign(dq[:, 0])])
    sol = asymmetric_least_squares(X, y[:, 0], 100.0)
    assert sol.converged
    s = np.where(y[:, 0] >= 0, 1.0, -1.0)
    sc = np.abs(X).max(axis=0)
    th = cp.Variable(3)
    z = 1e3 * cp.multiply(s, (X / sc) @ th - y[:, 0])
    cp.Problem(cp.Minimize(100 * cp.sum_squares(cp.pos(z)) + cp.sum_squares(cp.neg(z)))).solve(solver=cp.CLARABEL)
    np.testing.assert_allclose(sol.theta, th.value / sc, rtol=1e-5)


def _gaussian_expectile_fraction(w: float) -> float:
    """P(Z < −e) where e is the w/(1+w) expectile shift of a standard normal."""
    def eq(e):  # w E[(−e − Z)+] = E[(Z + e)+]  (over-estimation weighted w)
        c = -e
        under = norm.pdf(c) - c * norm.sf(c)  # E[(Z − c)+]
        over = c * norm.cdf(c) + norm.pdf(c)  # E[(c − Z)+]
        return w * over - under
    e = brentq(eq, 0.0, 5.0)
    return float(norm.cdf(-e))


def test_asymmetric_w100_over_estimates_at_most_5_percent():
    """Gaussian noise on a model that can shift (offset column, one-signed Δq): the w = 100 fit
    leaves the theoretical expectile fraction, P(Z < −1.72) ≈ 4.3 %, over-estimated."""
    rng = np.random.default_rng(4)
    n = 200_000
    tau = rng.uniform(20, 120, n)  # a gravity-loaded joint: τ of one sign
    dq = rng.normal(0, 0.5, n)
    y = 0.01 + 2e-4 * tau + 6e-3 * dq + 3e-4 * rng.standard_normal(n)
    X = np.column_stack([np.ones(n), tau, dq])
    sol = asymmetric_least_squares(X, y, 100.0)
    theory = _gaussian_expectile_fraction(100.0)
    assert 0.04 < theory < 0.045
    assert sol.over_fraction <= 0.05
    assert abs(sol.over_fraction - theory) < 0.004
    np.testing.assert_allclose(sol.theta[1:], [2e-4, 6e-3], rtol=0.01)  # slopes kept, offset moved down
    assert sol.theta[0] < 0.01 - 1.5 * 3e-4


def test_asymmetric_fit_handles_a_million_samples():
    rng = np.random.default_rng(5)
    n = 1_000_000
    tau = rng.uniform(-100, 100, n)
    dq = rng.normal(0, 1, n)
    band = rng.uniform(0, 1, n) * 0.15 * 2e-4 * np.abs(tau)  # friction band: adds to |Δq|
    y0 = 2e-4 * tau + 6e-3 * dq
    y = y0 + np.sign(y0) * band
    m = fit_asymmetric(tau[:, None], dq[:, None], y[:, None], 100.0)
    ls = fit_least_squares(tau[:, None], dq[:, None], y[:, None])
    assert m.info["per_joint"]["joint0"]["iterations"] < 20
    np.testing.assert_allclose(m.k_tau, 2e-4, rtol=0.03)  # the lower edge of the band
    assert ls.k_tau[0] > 2.1e-4  # least squares sits inside the band
    over = m.info["over_estimation_fraction"]["joint0"]
    assert over < 0.15 < ls.info["over_estimation_fraction"]["joint0"]


def test_two_stage_recovers_parameters():
    rng = np.random.default_rng(6)
    n = 20000
    tau = rng.uniform(-100, 100, (n, 3))
    dq = rng.normal(0, 0.8, (n, 3))
    dq[: n // 3] *= 1e-3  # quasi-static third of the log
    y = K_TAU * tau + K_V * dq + K_C * np.sign(dq) * (np.abs(dq) > 0.01)
    m = fit_two_stage(tau, dq, y, v_threshold=0.01, coulomb=True)
    # stage 1 neglects Kv q̇ on the slow samples (|q̇| < 3e-3 rad/s here): a 1e-5 bias at most
    np.testing.assert_allclose(m.k_tau, K_TAU, rtol=1e-4)
    np.testing.assert_allclose(m.k_v, K_V, rtol=1e-3)
    np.testing.assert_allclose(m.k_c, K_C, rtol=1e-2)


def _pwl(tau, dq, sl, sm, sr, b1, b2, c, kv):
    return c + sm * tau + (sl - sm) * np.minimum(0, tau - b1) + (sr - sm) * np.maximum(0, tau - b2) + kv * dq


def test_piecewise_linear_recovers_breakpoints_and_slopes():
    rng = np.random.default_rng(7)
    n = 30000
    tau = rng.uniform(-100, 100, (n, 1))
    dq = rng.normal(0, 0.5, (n, 1))
    pos = dq >= 0
    y = np.where(pos, _pwl(tau, dq, 2.5e-4, 0.5e-4, 3e-4, -20.0, 15.0, 1e-3, 5e-3),
                 _pwl(tau, dq, 3e-4, 0.8e-4, 2.5e-4, -15.0, 25.0, -1e-3, 5e-3))
    y = y + 2e-5 * rng.standard_normal((n, 1))
    m = fit_piecewise_linear(tau, dq, y)
    np.testing.assert_allclose(m.b1[0], [-20.0, -15.0], atol=1.0)
    np.testing.assert_allclose(m.b2[0], [15.0, 25.0], atol=1.0)
    np.testing.assert_allclose(m.s_mid[0], [0.5e-4, 0.8e-4], rtol=0.05)
    np.testing.assert_allclose(m.s_left[0], [2.5e-4, 3e-4], rtol=0.02)
    np.testing.assert_allclose(m.s_right[0], [3e-4, 2.5e-4], rtol=0.02)
    assert all(v["converged"] for v in m.info["per_joint"]["joint0"].values())
    # the central-slope bound is enforced
    mb = fit_piecewise_linear(tau, dq, y, central_slope=(1e-4, 2e-4))
    assert np.all(mb.s_mid >= 1e-4 - 1e-15) and np.all(mb.s_mid <= 2e-4 + 1e-15)


def test_current_model_recovers_parameters():
    rng = np.random.default_rng(8)
    n = 10000
    i = rng.uniform(-10, 10, (n, 2))
    dq = rng.normal(0, 1, (n, 2))
    k1, fv, fc = np.array([10.0, 16.0]), np.array([2.0, 3.0]), np.array([4.0, 5.0])
    tau = k1 * i - fv * dq - fc * np.sign(dq)
    m = fit_current_model(i, dq, tau)
    np.testing.assert_allclose(m.k1, k1, rtol=1e-9)
    np.testing.assert_allclose(m.fv, fv, rtol=1e-9)
    np.testing.assert_allclose(m.fc, fc, rtol=1e-9)
    np.testing.assert_allclose(m.current(m.torque(i, dq), dq), i, rtol=1e-9)


def test_motor_model_inverse():
    m = MotorModel(K_TAU, K_V, K_C)
    tau, dq, _ = _data(n=100)
    np.testing.assert_allclose(m.torque(m.delta_q(tau, dq), dq), tau, rtol=1e-9, atol=1e-9)
    assert MotorModel.from_dict(m.to_dict()).k_c.tolist() == K_C.tolist()


def test_every_actuator_model_round_trips_through_json():
    """to_dict → JSON → from_dict gives the same model: same predictions, names, method, info."""
    import json

    from sensorless.actuator.model import CurrentModel, PiecewiseLinearModel

    rng = np.random.default_rng(5)
    tau, dq, _ = _data(n=200)
    n = tau.shape[1]
    pwl = {k: rng.uniform(0.1, 1.0, (n, 2)) for k in ("c", "s_left", "s_mid", "s_right", "k_v")}
    pwl["b1"], pwl["b2"] = -rng.uniform(0.5, 1.0, (n, 2)), rng.uniform(0.5, 1.0, (n, 2))
    names = tuple(f"j{k}" for k in range(n))
    models = [MotorModel(K_TAU, K_V, K_C, joint_names=names, method="two_stage", info={"rmse": 0.1}),
              CurrentModel(rng.uniform(1, 2, n), K_V, K_C, joint_names=names, method="current_least_squares"),
              PiecewiseLinearModel(**pwl, joint_names=names, info={"n_samples": 200})]
    for m in models:
        back = type(m).from_dict(json.loads(json.dumps(m.to_dict())))
        assert (back.joint_names, back.method, back.info, back.n) == (m.joint_names, m.method, m.info, n)
        out = (back.torque(tau, dq), m.torque(tau, dq)) if isinstance(m, CurrentModel) else \
            (back.delta_q(tau, dq), m.delta_q(tau, dq))
        np.testing.assert_array_equal(*out)
    assert models[2].method == "piecewise_linear"


def test_errors():
    tau, dq, y = _data(n=200)
    with pytest.raises(ShapeMismatchError):
        fit_least_squares(tau, dq[:, :2], y)
    bad = y.copy()
    bad[17, 1] = np.nan
    with pytest.raises(NonFiniteError, match="sample 17"):
        fit_asymmetric(tau, dq, bad)
    with pytest.raises(ExcitationError):
        fit_least_squares(tau, np.zeros_like(dq), y)
    with pytest.raises(ExcitationError):
        fit_two_stage(tau, dq, y, v_threshold=100.0)


def test_saturated_samples_are_excluded_from_the_fits():
    """Where the drive saturates Δq keeps growing at constant torque; the ``valid`` mask from
    :func:`unsaturated` removes those samples and the fits recover the true model."""
    from sensorless.actuator import fit_asymmetric, fit_least_squares, unsaturated

    rng = np.random.default_rng(3)
    n, k_tau, k_v, limit = 20000, 2e-4, 5e-3, 100.0
    tau = rng.uniform(-150, 150, n)
    dq = rng.normal(0, 0.5, n)
    current = np.clip(tau, -limit, limit) / 10.0  # measured motor current [A], 10 Nm/A
    y = k_tau * tau + k_v * dq + rng.normal(0, 1e-5, n)
    sat = np.abs(tau) > limit
    y[sat] += 3e-3 * np.sign(tau[sat])  # position error runs away while the current is clipped
    ok = unsaturated(current[:, None] + rng.normal(0, 0.01, (n, 1)), limit / 10.0)
    assert ok[sat].sum() == 0 and ok[~sat].mean() > 0.95
    biased = fit_least_squares(tau, dq, y)
    clean = fit_least_squares(tau, dq, y, valid=ok)
    assert abs(biased.k_tau[0] / k_tau - 1) > 0.05
    assert abs(clean.k_tau[0] / k_tau - 1) < 1e-3 and abs(clean.k_v[0] / k_v - 1) < 1e-2
    asym = fit_asymmetric(tau, dq, y, 100.0, valid=ok)
    assert asym.info["n_valid"]["joint0"] == int(ok.sum())
    assert asym.info["over_estimation_fraction"]["joint0"] < 0.15
    with pytest.raises(ShapeMismatchError, match="valid mask"):
        fit_least_squares(tau, dq, y, valid=ok[:10])

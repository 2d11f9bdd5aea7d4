"""Rest-aware contact decisions (sensorless.estimation.static_band / monitoring) and the stick–slip
simulation they are tested on: oracles on synthetic observer outputs, no simulator needed."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from sensorless.data.integral_filter import observer_filter
from sensorless.errors import DataError
from sensorless.estimation.collision import observer_warmup, quiet_mask
from sensorless.estimation.monitoring import still_mask
from sensorless.estimation.static_band import (STATUS, StaticFriction, classify_at_rest, model_static_friction,
                                               rest_aware_thresholds, rest_intervals)
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot
from sensorless_studies.simulation.held_arm import Stiction, karnopp_step, noise_implied_force


@pytest.mark.parametrize("order", [1, 2])
def test_observer_warmup_is_when_the_filter_has_converged(order):
    """The warm-up is the last time L(s)'s step response (zero initial state) is off by more than
    the tolerance: a few time constants 1/K, longer for order 2, and scaling as 1/K."""
    dt, K = 2e-3, 50.0
    w = observer_warmup(K, order, dt)
    _, b, a = observer_filter(K, order, dt)
    step = signal.lfilter(b, a, np.ones(2000))
    i = int(round(w / dt))
    assert np.all(np.abs(step[i:] - 1) <= 1e-3) and np.abs(step[i - 1] - 1) > 1e-3
    assert 4.0 / K < w < 12.0 / K
    assert observer_warmup(2 * K, order, dt / 2) == pytest.approx(w / 2, rel=0.05)
    if order == 2:
        assert w > observer_warmup(K, 1, dt)


def test_quiet_window_is_relative_like_trim():
    """'0:1' is the first second of a log stamped in Unix time; 'abs:' reads the stamps; the warm-up
    is left out; errors name the window and the log's span."""
    t = 1_712_345_678.0 + np.arange(2000) * 2e-3
    rel = quiet_mask(t, "0:1", "log.npz")
    assert rel.sum() == 501 and rel[0] and not rel[501]
    np.testing.assert_array_equal(quiet_mask(t, f"abs:{t[0]}:{t[0] + 1.0}"), rel)
    np.testing.assert_array_equal(quiet_mask(t, "-1:"), t >= t[-1] - 1.0)
    warm = t < t[0] + 0.2
    assert quiet_mask(t, "0:1", exclude=warm).sum() == 401
    with pytest.raises(DataError, match=r"quiet segment 0:0.1 holds 51 samples, 0 after the observer warm-up .* spans 3.998 s"):
        quiet_mask(t, "0:0.1", "log.npz", exclude=t < t[0] + 0.2)
    with pytest.raises(DataError, match="holds 0 samples"):
        quiet_mask(t, "50:60", "log.npz")
    with pytest.raises(DataError, match="`quiet`"):
        quiet_mask(t, "3", "log.npz")


def test_karnopp_stick_breakaway_and_slide():
    """One joint: held while |u| ≤ f_s (f = u, v̇ = 0); beyond it the joint breaks away against
    f_s; sliding it meets fc + (fs − fc) e^{−(v/vs)²} against its velocity."""
    st = Stiction(np.array([1.0]), np.array([1.5]), 0.05)
    M, dt = np.array([[0.2]]), 1e-3
    a, f = karnopp_step(M, np.array([1.4]), np.zeros(1), dt, st)
    assert a[0] == 0 and f[0] == pytest.approx(1.4)
    a, f = karnopp_step(M, np.array([-1.6]), np.zeros(1), dt, st)
    assert f[0] == pytest.approx(-1.5) and a[0] == pytest.approx(-0.1 / 0.2)
    a, f = karnopp_step(M, np.array([0.0]), np.array([0.5]), dt, st)
    assert f[0] == pytest.approx(1.0 + 0.5 * np.exp(-100)) and a[0] == pytest.approx(-f[0] / 0.2)
    # a slow joint that would reverse within the step is stopped and held
    a, f = karnopp_step(M, np.array([0.5]), np.array([-1e-3]), dt, st)
    assert a[0] == pytest.approx(1.0) and f[0] == pytest.approx(0.5 - 0.2)
    with pytest.raises(Exception, match="fc ≤ fs"):
        Stiction(np.array([1.0]), np.array([0.5]))


def test_two_joints_stick_with_coupling():
    """Coupled inertia: the free joint's acceleration loads the stuck one through M; the stuck
    joint's friction is what the partitioned equations need, and it releases past f_s."""
    st = Stiction(np.array([0.5, 0.5]), np.array([1.0, 1.0]), 0.05)
    M = np.array([[1.0, 0.4], [0.4, 1.0]])
    a, f = karnopp_step(M, np.array([3.0, 0.0]), np.zeros(2), 1e-3, st)
    # joint 0 breaks away (|u0| > fs) with f0 = 1; joint 1 stays: f1 = u1 − M10 a0, a0 = (u0 − f0)/M00
    assert a[1] == 0 and a[0] == pytest.approx(2.0) and f[1] == pytest.approx(-0.8)
    a, f = karnopp_step(M, np.array([6.0, 0.0]), np.zeros(2), 1e-3, st)
    assert a[0] > 0 and a[1] < 0 and abs(f[1]) == pytest.approx(1.0)
    np.testing.assert_allclose(M @ a, np.array([6.0, 0.0]) - f)


def test_model_static_friction_from_the_joint_terms():
    """f_s = fc + (fs − fc) per joint, fc where a joint has no Stribeck term, NaN without fc."""
    robot = load_robot("ur5")
    st = ModelStructure(robot, joint_terms={"shoulder_pan_joint": ("fv",), "elbow_joint": ("fv", "fc"),
                                            "*": ("fv", "fc", "stribeck", "offset")}, coulomb_smoothing=0.01)
    p = st.prior()
    for j, (fc, ds) in zip(robot.actuated_joints, [(0, 0), (2.0, 0.8), (1.5, 0), (0.6, -0.1), (0.5, 0.2), (0.4, 0.1)]):
        if "fc" in st.terms_of(j):
            p[st.joint_term_index(j, "fc")] = fc
        if "stribeck" in st.terms_of(j):
            p[st.joint_term_index(j, "stribeck")] = ds
    sf = model_static_friction(st, p, list(robot.actuated_joints))
    assert np.isnan(sf.values[0]) and sf.sources[0] == "none"
    np.testing.assert_allclose(sf.values[1:], [2.8, 1.5, 0.6, 0.7, 0.5])
    assert "Stribeck" in sf.sources[1] and sf.sources[2] == "model: Coulomb fc"


def _rest_log(seed=0, n=6000, dt=2e-3):
    """Two joints held still, r = level + noise: joint a's stick torque steps inside the band at
    t = 4 s (after moving 0.2 s), joint b is pushed at rest beyond it at t = 8 s."""
    rng = np.random.default_rng(seed)
    t = 100.0 + np.arange(n) * dt
    r = rng.normal(size=(n, 2)) * 0.01
    rest = np.ones((n, 2), bool)
    ts = t - t[0]
    r[:, 0] += np.where(ts < 4.0, 0.3, -0.6)
    moving = (ts >= 3.8) & (ts < 4.0)
    rest[moving, 0] = False
    r[moving, 0] += 2.0  # the friction error of the slide
    r[:, 1] += np.where((ts >= 8.0) & (ts < 8.5), 1.8, 0.2)
    return t, r, rest


def test_dead_zone_and_holding_level_on_a_held_log():
    """A stick torque that moves inside ±f_s is not a contact; the reported torque at rest is the
    change since the joint settled (noise), while r outside the band is a contact at rest whose
    excess over the band is a lower bound of the external torque."""
    t, r, rest = _rest_log()
    static = StaticFriction(["a", "b"], np.array([1.0, 1.0]), ["given", "given"])
    quiet = quiet_mask(t, "0:1", exclude=t < t[0] + 0.14)
    th = rest_aware_thresholds(r, rest, quiet, static, k=5.0, margin=0.0)
    assert th.bias_rest == pytest.approx([0.3, 0.2], abs=0.005) and th.centre == pytest.approx([0.0, 0.0])
    tr = classify_at_rest(r, t, rest, th, quiet=quiet, warmup=0.14, settle=0.14)
    ts = t - t[0]
    assert np.isnan(tr.tau_ext[ts < 0.14]).all() and (tr.status[ts < 0.14] == STATUS.index("warmup")).all()
    after = ts > 4.3
    assert not tr.contact[after & (ts < 8.0)].any()
    np.testing.assert_allclose(tr.holding[ts > 4.5, 0], -0.6, atol=0.01)
    assert np.std(tr.tau_ext[after & (ts < 8.0), 0]) < 0.015 and abs(np.mean(tr.tau_ext[after & (ts < 8.0), 0])) < 0.01
    flag, contacts, band = rest_intervals(tr, t, r, th, min_duration=0.02, merge_gap=0.05)
    starts = sorted(round(iv.start - t[0], 2) for iv in contacts)
    assert starts[0] == pytest.approx(3.8, abs=0.01)  # the slide, judged in motion
    pushed = [iv for iv in contacts if iv.start - t[0] > 7.9]
    assert len(pushed) == 1 and pushed[0].state == {"b": "rest"}
    assert pushed[0].band_excess["b"] == pytest.approx(0.8, abs=0.06)
    assert pytest.approx(8.0, abs=0.01) == pushed[0].start - t[0]
    assert pushed[0].end - t[0] == pytest.approx(8.5, abs=0.01)
    # the slide is a contact in motion; once stopped, the new stick level is inside the band: a change
    # friction explains until the level is re-estimated (one settling time); the same after the push
    assert contacts[0].end - t[0] == pytest.approx(4.0, abs=0.01)
    assert [(round(iv.start - t[0], 2), iv.joints) for iv in band] == [(4.0, ["a"]), (8.5, ["b"])]
    assert [round(iv.end - t[0], 2) for iv in band] == pytest.approx([4.14, 8.64], abs=0.01)


def test_without_the_model_s_friction_the_band_comes_from_the_quiet_window_labelled():
    t, r, rest = _rest_log()
    r[:, 0] += 0.5  # joint a's quiet level 0.8: friction by assumption, so |b| bounds f_s from below
    static = StaticFriction(["a", "b"], np.array([np.nan, 1.0]), ["none", "given"])
    quiet = quiet_mask(t, "0:1")
    th = rest_aware_thresholds(r, rest, quiet, static, k=5.0, margin=0.0)
    assert th.band[0] == pytest.approx(0.8, abs=0.005) and "lower bound" in th.band_source[0]
    with pytest.raises(DataError, match="margin"):
        rest_aware_thresholds(r, rest, quiet, static, k=5.0, margin=-1.0)


def test_still_mask_ignores_velocity_spikes():
    t = np.arange(100) * 0.002
    v = np.zeros((100, 1))
    v[30] = 1.0  # one-sample spike
    v[60:80] = 0.5  # a 40 ms motion
    m = still_mask(t, v, np.array([0.1]), blip=0.02)
    assert m[30, 0] and not m[60:80, 0].any() and m[81:, 0].all()
    v[85:87] = 0.5  # a reversal-like still run of 6 samples between motions is not a rest with hold = 0.02 s
    v[87:90] = 0.0
    v[90:] = 0.5
    m = still_mask(t, v, np.array([0.1]), blip=0.02, hold=0.02)
    assert m[:60, 0].all() and not m[60:, 0].any()


def test_noise_implied_force_is_the_pseudo_inverse_map():
    """Monte Carlo oracle: the RMS of (Jᵀ)⁺ n over torque noise n."""
    import pinocchio as pin

    robot = load_robot("ur5")
    q = np.array([0.3, -1.2, 1.4, -1.6, -1.5, 0.2])
    f = noise_implied_force(robot, q, "tool0", 0.05)
    J = pin.computeFrameJacobian(robot.model, robot.model.createData(), q, robot.frame_id("tool0"),
                                 pin.LOCAL_WORLD_ALIGNED)[:3]
    n = np.random.default_rng(0).normal(size=(20000, 6)) * 0.05
    F = np.linalg.lstsq(J.T, n.T, rcond=None)[0].T
    assert f == pytest.approx(np.sqrt(np.mean(np.sum(F**2, axis=1))), rel=0.02)


def test_contact_bounds_are_where_a_sample_becomes_a_contact():
    """monitor.png's threshold lines (MonitorTrace.contact_bounds): the reported τ_ext leaves them exactly on
    the samples classified as contact, at rest (the dead zone, shifted by the holding level) and in motion (±kσ)."""
    t, r, rest = _rest_log()
    static = StaticFriction(["a", "b"], np.array([1.0, 1.0]), ["given", "given"])
    quiet = quiet_mask(t, "0:1", exclude=t < t[0] + 0.14)
    th = rest_aware_thresholds(r, rest, quiet, static, k=5.0, margin=0.0)
    tr = classify_at_rest(r, t, rest, th, quiet=quiet, warmup=0.14, settle=0.14)
    lo, hi = tr.contact_bounds(r, th)
    live = ~np.isnan(tr.tau_ext)
    outside = (tr.tau_ext < lo) | (tr.tau_ext > hi)
    np.testing.assert_array_equal(outside[live], (tr.status == STATUS.index("contact"))[live])
    assert np.isnan(lo[~live]).all()
    ts = t - t[0]
    assert (hi - lo)[(ts > 2) & (ts < 3), 0] == pytest.approx(2 * (1.0 + 5.0 * th.sigma_rest[0]))  # at rest: the band
    assert (hi - lo)[(ts > 3.95) & (ts < 4.0), 0] == pytest.approx(2 * 5.0 * th.sigma_move[0])  # sliding (settled: 0.14 s after leaving rest): ±kσ

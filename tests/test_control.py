"""Controller: gain mapping, inverse dynamics vs RNEA, the Δq law, closed loop on the simulated leg."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sensorless.actuator import MotorModel
from sensorless.control import (
    DeltaQGains,
    InverseDynamics,
    JointTorqueController,
    Reference,
    StreamingSavgol,
    TorqueControlLoop,
    TorqueGains,
    contact_wrench_from_ft,
    damped_gains,
    from_delta_q_gains,
    to_delta_q_gains,
)
from sensorless.errors import DataError
from sensorless_studies.simulation.leg_model import (
    FT_FRAME,
    SOLE_FRAME,
    plate_inertia,
    talos_right_leg,
)
from sensorless_studies.simulation.leg_protocols import Q_AIR, Q_CONTACT
from sensorless_studies.simulation.position_controlled import (
    ActuatorParams,
    PositionControlledLeg,
    SensorNoise,
    leg_estimator,
    simulate,
)


@pytest.fixture(scope="module")
def leg():
    return talos_right_leg()


def test_gain_mapping_round_trip():
    rng = np.random.default_rng(0)
    kt = rng.uniform(1e-4, 4e-4, 6)
    g = TorqueGains(kp=rng.uniform(0, 2, 6), ks=rng.uniform(100, 5000, 6), kd=rng.uniform(1, 80, 6), kf=rng.uniform(0, 2, 6))
    d = to_delta_q_gains(g, kt)
    back = from_delta_q_gains(d, kt)
    for name in ("kp", "ks", "kd", "kf"):
        np.testing.assert_allclose(getattr(back, name), getattr(g, name), rtol=1e-12)
    np.testing.assert_allclose(d.k6, kt * (1 + g.kp) * g.ks, rtol=1e-14)
    # position control is K6 = 1 with no torque feedback: Ks = 1 / Kτ
    pc = from_delta_q_gains(DeltaQGains(np.ones(6), np.zeros(6), np.zeros(6), np.zeros((6, 6))), kt)
    np.testing.assert_allclose(pc.ks, 1 / kt, rtol=1e-14)
    # a K9 that is not (Kτ + K8) ⊗ Kf has no joint-independent Kf
    bad = DeltaQGains(d.k6, d.k7, d.k8, rng.uniform(0, 1e-3, (6, 6)))
    with pytest.raises(DataError):
        from_delta_q_gains(bad, kt)


def test_inverse_dynamics_equals_rnea(leg):
    rng = np.random.default_rng(1)
    idyn = InverseDynamics(leg, contact_frame=SOLE_FRAME)
    m, d = leg.model.copy(), None
    m.armature[:] = 0
    d = m.createData()
    lo, hi = leg.position_limits()
    fid = leg.frame_id(SOLE_FRAME)
    for _ in range(10):
        q = rng.uniform(lo, hi)
        dq, ddq = rng.normal(size=6), rng.normal(size=6)
        tau, f_star = idyn.torque(q, dq, q, dq, ddq, ks=500.0, kd=20.0)
        np.testing.assert_allclose(tau, pin.rnea(m, d, q, dq, ddq), atol=1e-10)
        assert f_star is None
        # with a desired contact wrench: RNEA with that wrench applied at the sole (world axes)
        f_d = rng.normal(0, 50, 6)
        tau_f, _ = idyn.torque(q, dq, q, dq, ddq, 500.0, 20.0, f_d=f_d)
        pin.framesForwardKinematics(m, d, q)
        oMf = d.oMf[fid]
        w_local = pin.Force(oMf.rotation.T @ f_d[:3], oMf.rotation.T @ f_d[3:])
        fext = pin.StdVec_Force()
        for _ in range(m.njoints):
            fext.append(pin.Force.Zero())
        fext[m.frames[fid].parentJoint] = m.frames[fid].placement.act(w_local)
        np.testing.assert_allclose(tau_f, pin.rnea(m, d, q, dq, ddq, fext), atol=1e-9)
        # force feedback: f* = f_d + Kf (f_d − f̂)
        _, fs = idyn.torque(q, dq, q, dq, ddq, 0.0, 0.0, f_d=f_d, f_meas=f_d - 10.0, kf=0.5)
        np.testing.assert_allclose(fs, f_d + 5.0)


def test_delta_q_law_matches_closed_form(leg):
    """The implemented chain (inverse dynamics → τ* → Δq) equals the documented Δq form."""
    rng = np.random.default_rng(2)
    kt, kv = rng.uniform(1e-4, 4e-4, 6), rng.uniform(3e-3, 8e-3, 6)
    motor = MotorModel(kt, kv)
    g = TorqueGains(kp=0.4, ks=rng.uniform(500, 3000, 6), kd=rng.uniform(5, 50, 6), kf=rng.uniform(0, 1, 6))
    idyn = InverseDynamics(leg, contact_frame=SOLE_FRAME)
    jtc = JointTorqueController(motor, g.kp)
    q, q_d = Q_AIR + rng.normal(0, 0.05, 6), Q_AIR
    dq, dq_d, ddq_d = rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
    f_d, f_hat, tau_hat = rng.normal(0, 50, 6), rng.normal(0, 50, 6), rng.normal(0, 20, 6)
    tau_d, _ = idyn.torque(q, dq, q_d, dq_d, ddq_d, g.ks, g.kd, f_d, f_hat, g.kf)
    dq_cmd = jtc.delta_q(tau_d, tau_hat, dq)
    G = to_delta_q_gains(g, kt)
    J = idyn.jacobian(q)
    tau_ff = idyn.feedforward(q, dq, ddq_d, f_d)
    closed = ((kt + G.k8) * tau_ff - G.k8 * tau_hat + G.k6 * (q_d - q) + G.k7 * (dq_d - dq)
              - (G.k9 * J.T) @ (f_d - f_hat) + kv * dq)
    np.testing.assert_allclose(dq_cmd, closed, rtol=1e-10, atol=1e-14)


def test_streaming_savgol_exact_on_quadratics():
    dt = 1e-3
    f = StreamingSavgol(15, 2, dt, 2)
    t = np.arange(40) * dt
    x = np.column_stack([1 + 2 * t + 3 * t**2, -t**2])
    for k in range(40):
        out = f.push(x[k])
    np.testing.assert_allclose(out[0], x[-1], atol=1e-12)
    np.testing.assert_allclose(out[1], [2 + 6 * t[-1], -2 * t[-1]], atol=1e-8)
    np.testing.assert_allclose(out[2], [6.0, -2.0], atol=1e-5)


def test_contact_wrench_from_ft_matches_simulated_contact():
    sim = PositionControlledLeg("contact", noise=SensorNoise.none(), model_error=0.0)
    qd = Q_CONTACT + np.array([0, 0, 0.004, -0.008, 0.004, 0])  # press into the floor
    lg = simulate(sim, lambda k, r: qd, 800)
    f = contact_wrench_from_ft(sim.robot, lg.q[-1], lg.ft[-1], FT_FRAME, SOLE_FRAME, plate_inertia())
    assert lg.contact[-1][2] > 200
    np.testing.assert_allclose(f, lg.contact[-1], atol=0.05 + 1e-3 * np.abs(lg.contact[-1]).max())


def test_closed_loop_torque_control_tracks(leg):
    """Exact actuator knowledge, no noise: torque control (K6 = 1) tracks a sinusoid better than
    the drive's own position control, and the estimated torque follows τ_d."""
    dt, n = 1e-3, 2000
    act = ActuatorParams()
    tm = act.true_model()
    motor = MotorModel(tm["k_tau_static"], tm["k_v"])
    t = np.arange(n) * dt
    w = 2 * np.pi * 0.75
    amp = np.array([0.1, 0.08, 0.3, 0.35, 0.2, 0.08])
    q = Q_AIR + amp * np.sin(w * t)[:, None]
    ref = Reference(q, amp * w * np.cos(w * t)[:, None], -amp * w**2 * np.sin(w * t)[:, None])
    sim = PositionControlledLeg("air", noise=SensorNoise.none(), model_error=0.0)
    pos = simulate(sim, lambda k, r: q[k], n)
    inertia = np.diag(InverseDynamics(leg).mass_matrix(Q_AIR)) + act.rotor_inertia
    loop = TorqueControlLoop(leg_estimator(sim.robot), motor, damped_gains(1.0, motor.k_tau, 0.3, inertia), ref, dt)
    sim.reset(q[0])
    tc = simulate(sim, loop, n)
    e_pos = np.abs(q - pos.q_true)[200:].mean(axis=0)
    e_tc = np.abs(q - tc.q_true)[200:].mean(axis=0)
    assert np.all(e_tc < e_pos)
    # bounded: (the reference starts moving at t = 0 while the leg is at rest: skip 0.2 s)
    assert np.all(np.abs(q - tc.q_true)[200:].max(axis=0) < np.radians(1.0))
    # the in-loop F/T + IMU estimate (causal filters) follows the true joint torque
    tau_hat = np.array(loop.trace["tau_hat"])
    true = tc.tau[: len(tau_hat)]
    rmse = np.sqrt(((tau_hat - true)[200:] ** 2).mean(axis=0))
    span = np.ptp(true[200:], axis=0)
    assert np.all(rmse < 0.2 * span + 0.5), (rmse, span)  # causal derivatives: ~10–16 % here
    # and no chattering: high-frequency torque content as low as under position control
    hf = lambda x: np.abs(np.diff(x[200:], 2, axis=0)).mean(axis=0)
    assert np.all(hf(tc.tau) < 3 * hf(pos.tau) + 0.05)

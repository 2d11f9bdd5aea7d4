"""The compiled momentum-observer step (estimation.native_observer, regressor/observer_kernel.cpp): the
same numbers as the Python step to 1e-10 on UR5, Solo12 (floating base) and the dVRK PSM (transmission)
with their friction terms, the collision check's flag, and the fallbacks with their reasons."""

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import RobotModelError, ShapeMismatchError
from sensorless.estimation.contact_stream import ContactStream
from sensorless.estimation.friction_dynamics import FrictionDynamics
from sensorless.estimation.momentum import MomentumDynamics, MomentumObserver
from sensorless.estimation import native_observer as mod
from sensorless.estimation.native_observer import native_observer, random_states
from sensorless.regressor import native
from sensorless.regressor.terms import ModelStructure
from sensorless.robot import load_robot
from sensorless.robots.dvrk_psm import psm_structure

pytestmark = pytest.mark.skipif(not mod.available(), reason="the C++ kernel with the observer step is not built "
                                "(python -m sensorless.regressor.native_build)")


def _params(st, rng) -> np.ndarray:
    """The model's prior inertias (random bodies for a transmission) with every joint/drive term non-zero."""
    p = st.prior() if not hasattr(st, "drives") or not st.drives else np.zeros(st.n_params)
    nb = st.n_body_params
    if st.drives:
        for k in range(st.robot.n_bodies):
            p[10 * k: 10 * k + 10] = pin.Inertia.Random().toDynamicParameters()
    p[nb:] = rng.uniform(0.05, 0.5, st.n_params - nb)
    return p


def ur5_dynamics(rng, **kw) -> MomentumDynamics:
    robot = load_robot("ur5")
    j = robot.actuated_joints
    st = ModelStructure(robot, joint_terms=("fv", "fc", "stribeck", "offset", "armature"),
                        coulomb_smoothing={n: e for n, e in zip(j, (0.0, 0.02, 0.05, 0.01, 0.0, 0.03))},
                        stribeck_velocity={n: 0.1 + 0.05 * k for k, n in enumerate(j)},
                        rest_velocity={j[0]: 1e-3, j[3]: 5e-4}, **kw)
    return MomentumDynamics(st, _params(st, rng))


def solo_dynamics(rng) -> MomentumDynamics:
    st = ModelStructure(load_robot("solo12", floating_base=True), joint_terms=("fv", "fc", "offset", "armature"),
                        coulomb_smoothing=0.02)
    return MomentumDynamics(st, _params(st, rng))


def psm_dynamics(rng) -> MomentumDynamics:
    st = psm_structure(drives="motors", coulomb_smoothing=0.02)
    return MomentumDynamics(st, _params(st, rng))


def _walk(dyn, N: int, rng):
    """A random walk of states (smooth enough for the presliding state to move both ways), with a few
    velocities inside the rest band and the Coulomb transition."""
    q, v, tau, bq, bv = random_states(dyn, 1, rng)
    nj = q.shape[1]
    dv = rng.standard_normal((N, nj)) * 0.05
    V = np.cumsum(dv, axis=0) * np.where(rng.uniform(size=(N, 1)) < 0.1, 1e-3, 1.0)
    Q = q[0] + np.cumsum(V, axis=0) * 1e-2
    T = tau[0] + np.cumsum(rng.standard_normal((N, tau.shape[1])), axis=0) * 0.1
    if bq[0] is None:
        return Q, V, T, [None] * N, [None] * N
    BQ = np.tile(bq[0], (N, 1))
    BQ[:, :3] += np.cumsum(rng.standard_normal((N, 3)) * 1e-3, axis=0)
    BV = bv[0] + np.cumsum(rng.standard_normal((N, 6)) * 0.01, axis=0)
    return Q, V, T, BQ, BV


def _both(dyn, N=300, seed=1, **kw):
    rng = np.random.default_rng(seed)
    Q, V, T, BQ, BV = _walk(dyn, N, rng)
    fast, slow = MomentumObserver(dyn, dt=1e-3, **kw), MomentumObserver(dyn, dt=1e-3, compiled=False, **kw)
    assert fast.compiled, fast.compiled_reason
    assert not slow.compiled and "compiled=False" in slow.compiled_reason
    r_c = np.array([fast.step(Q[i], V[i], T[i], BQ[i], BV[i]) for i in range(N)])
    r_p = np.array([slow.step(Q[i], V[i], T[i], BQ[i], BV[i]) for i in range(N)])
    return r_c, r_p


@pytest.mark.parametrize("make", [ur5_dynamics, solo_dynamics, psm_dynamics], ids=["ur5", "solo12", "dvrk_psm"])
@pytest.mark.parametrize("order", [1, 2])
def test_compiled_step_equals_python_step(make, order):
    dyn = make(np.random.default_rng(0))
    r_c, r_p = _both(dyn, order=order, gain=40.0)
    assert np.abs(r_p).max() > 1e-3  # a real signal, not zeros
    np.testing.assert_allclose(r_c, r_p, rtol=0, atol=1e-10 * max(1.0, np.abs(r_p).max()))


def test_product_law_and_presliding_state():
    robot = load_robot("ur5")
    j = robot.actuated_joints
    dyn = ur5_dynamics(np.random.default_rng(3), friction_law="product")
    r_c, r_p = _both(dyn)
    np.testing.assert_allclose(r_c, r_p, rtol=0, atol=1e-10 * max(1.0, np.abs(r_p).max()))
    st = ModelStructure(robot, joint_terms={n: ("fv", "fc", "presliding") if k < 3 else ("fv", "offset")
                                            for k, n in enumerate(j)},
                        presliding={j[0]: {"k": 200.0, "play": 1e-4}, j[1]: {"k": 50.0, "play": 0.0},
                                    j[2]: {"k": 500.0, "play": 2e-3}})
    dyn = MomentumDynamics(st, _params(st, np.random.default_rng(4)))
    assert dyn.friction_integrator() is not None
    r_c, r_p = _both(dyn, order=2)
    np.testing.assert_allclose(r_c, r_p, rtol=0, atol=1e-10 * max(1.0, np.abs(r_p).max()))


def test_step_into_reset_and_kernel_loop():
    dyn = ur5_dynamics(np.random.default_rng(5))
    rng = np.random.default_rng(6)
    Q, V, T, _, _ = _walk(dyn, 50, rng)
    obs = MomentumObserver(dyn, dt=1e-3)
    first = np.array([obs.step(Q[i], V[i], T[i]) for i in range(50)])
    obs.reset()
    out = np.empty(dyn.n)
    again = np.array([obs.step_into(out, Q[i], V[i], T[i]).copy() for i in range(50)])
    np.testing.assert_array_equal(first, again)
    kern = obs.kernel()
    kern.reset()
    R, _, _, _ = kern.run(kern.inputs(Q, V, T))
    np.testing.assert_array_equal(R, first)
    with pytest.raises(ShapeMismatchError, match="6 joints"):
        obs.step(Q[0][:5], V[0], T[0])


def test_bare_loop_matches_pinocchio():
    dyn = ur5_dynamics(np.random.default_rng(7))
    kern = MomentumObserver(dyn, dt=1e-3).kernel()
    q, v, tau, _, _ = random_states(dyn, 4, np.random.default_rng(8))
    Qt, Vt = kern.tree_states(kern.inputs(q, v, tau))
    _, out = kern.bare(Qt, Vt, values=True)
    nv = dyn.model.nv
    data = dyn.model.createData()
    for i in range(4):
        M = np.triu(pin.crba(dyn.model, data, Qt[i]))
        ctv = pin.computeCoriolisMatrix(dyn.model, data, Qt[i], Vt[i]).T @ Vt[i]
        g = pin.computeGeneralizedGravity(dyn.model, data, Qt[i])
        np.testing.assert_allclose(np.triu(out[i, : nv * nv].reshape(nv, nv)), M, atol=1e-12)
        np.testing.assert_allclose(out[i, nv * nv:], np.concatenate([ctv, g]), atol=1e-12)


def test_contact_flag_same_compiled_and_python():
    dyn = ur5_dynamics(np.random.default_rng(9))
    rng = np.random.default_rng(10)
    Q, V, T, _, _ = _walk(dyn, 400, rng)
    T[250:300, 2] += 8.0  # a push on one joint
    names = [dyn.names[i] for i in dyn.actuated_rows]
    flags, taus = [], []
    for compiled in (None, False):
        obs = MomentumObserver(dyn, gain=50.0, dt=1e-3, compiled=compiled)
        mon = ContactStream(obs, names, bias=np.zeros(6), threshold=np.full(6, 2.0))
        f, te = [], []
        for i in range(400):
            f.append(mon.step(Q[i], V[i], T[i]))
            te.append(mon.tau_ext.copy())
        flags.append(np.array(f))
        taus.append(np.array(te))
        assert mon.compiled == (compiled is None)
    np.testing.assert_array_equal(flags[0], flags[1])
    assert flags[0][260:300].all() and not flags[0][: mon.warmup_steps].any()
    # the offline observer and detect_contacts' test give the same flags after the warm-up
    from sensorless.data.trajectory import Trajectory
    from sensorless.estimation.collision import Thresholds, detect_contacts

    robot = dyn.structure.robot
    traj = Trajectory(t=np.arange(400) * 1e-3, q=Q, v=V, tau=T, joint_names=list(robot.joint_names))
    raw = -MomentumObserver(dyn, gain=50.0).run(traj).tau_ext
    th = Thresholds(names, np.zeros(6), np.full(6, 1.0), 2.0, 100)
    offline, _ = detect_contacts(raw, traj.t, th)
    offline[: mon.warmup_steps] = False
    np.testing.assert_array_equal(flags[0], offline)
    np.testing.assert_allclose(taus[0], taus[1], atol=1e-10 * max(1.0, np.abs(taus[1]).max()))


def test_fallbacks_name_their_reason(monkeypatch):
    # a friction-only model runs in Python
    from sensorless.regressor.friction_state import FrictionLaw

    class _Model:
        joint_names_ = ["j1"]
        laws_ = {"j1": FrictionLaw("static", {"fc": 0.2, "fv": 0.1}, eps=0.01)}

    obs = MomentumObserver(FrictionDynamics(_Model()), dt=1e-3)
    assert not obs.compiled and "FrictionDynamics" in obs.compiled_reason
    r = obs.step([0.1], [0.2], [0.3])  # the Python step still works
    assert r.shape == (1,)
    with pytest.raises(RobotModelError, match="FrictionDynamics"):
        MomentumObserver(FrictionDynamics(_Model()), compiled=True)
    # a model whose step the kernel does not reproduce is refused, with the size of the difference
    dyn = ur5_dynamics(np.random.default_rng(11))
    monkeypatch.setattr(mod, "_describe", _wrong_friction(mod._describe))
    def python_observer(dyn, gain, order, dt):
        return MomentumObserver(dyn, gain=gain, order=order, dt=dt, compiled=False)

    nat, reason = native_observer(dyn, reference=python_observer)
    assert nat is None and "differs from the Python step" in reason
    # a kernel built before the observer step
    monkeypatch.setattr(mod, "_lib", lambda: None)
    nat, reason = native_observer(dyn)
    assert nat is None and "built before the observer step" in reason
    monkeypatch.undo()
    # the kernel turned off
    monkeypatch.setenv("SENSORLESS_NATIVE", "0")
    native._lib.cache_clear()
    mod._lib.cache_clear()
    try:
        obs = MomentumObserver(ur5_dynamics(np.random.default_rng(12)), dt=1e-3)
        assert not obs.compiled and "SENSORLESS_NATIVE=0" in obs.compiled_reason
    finally:
        monkeypatch.delenv("SENSORLESS_NATIVE")
        native._lib.cache_clear()
        mod._lib.cache_clear()


def _wrong_friction(describe):
    """_describe with one more friction term than the model has."""
    def wrapped(lib, dyn):
        h, reason, sizes = describe(lib, dyn)
        if h is not None:
            lib.slo_add_joint_friction(h, 0, 0.0, 0.0, 1.0, 0, 0.0, 0.0, 0.0, 0.7)
        return h, reason, sizes
    return wrapped


def test_benchmark_record():
    from sensorless_studies.benchmarks.observer import run

    res = run(samples=400, python_samples=20, rounds=2, robots=("ur5", "dvrk_psm"))
    for name in ("ur5", "dvrk_psm"):
        r = res["robots"][name]
        assert r["compiled"] and r["reason"] is None and r["step"]["samples"] == 400
        for part in ("step", "step_into", "kernel_loop", "bare_cpp", "python_step"):
            s = r[part]
            assert 0 < s["p50_us"] <= s["p99_us"] <= s["p999_us"] <= s["max_us"] and s["over_1ms"] >= 0
        assert len(r["ratio_rounds"]) == 2 and r["ratio"] > 0 and r["speedup_vs_python"] > 0
    assert len(res["load_average_before"]) == 3 and res["kernel"]

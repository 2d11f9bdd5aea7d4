"""`sensorless stream`: the per-sample monitor equals the offline observer, records, endpoints, clean stops."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.errors import DataError, OptionError
from sensorless.estimation.momentum import MomentumDynamics, MomentumObserver
from sensorless.estimation.monitored import MonitoredTorque, cartesian_force, monitored_torque
from sensorless.estimation.monitoring import MonitorSettings, monitor_log
from sensorless.realtime import LatencyHistogram, RecordLayout, StreamMonitor, StreamThresholds, parse_endpoint
from sensorless.realtime.ros2 import joint_state_sample, stamp_gap, stamp_seconds
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot
from sensorless_studies.simulation.arm_push import Push, simulate_pushes
from sensorless.testing import NoiseSpec, perturbed_truth

PUSHES = [Push(4.0, 4.6, (0.0, 0.0, -30.0), "tool0"), Push(5.5, 6.0, (20.0, -10.0, 0.0), "tool0")]


@pytest.fixture(scope="module")
def arm():
    """A UR5 pushed twice after a 3 s contact-free start (200 Hz, noisy), its true model and thresholds."""
    nom = load_robot("ur5")
    truth = perturbed_truth(nom, rng=1)
    traj, gt = simulate_pushes(truth, nom, PUSHES, duration=6.5, seed=3, log_rate=200.0,
                               noise=NoiseSpec(q=1e-4, v=1e-2, tau=0.2))
    dyn = MomentumDynamics(ModelStructure(truth.robot, coulomb_smoothing=gt.coulomb_velocity), truth.parameters())
    mon = monitor_log(dyn, traj, MonitorSettings(quiet="0:3"))
    return traj, dyn, StreamThresholds.from_result(mon)


def _stream(sm: StreamMonitor, traj) -> np.ndarray:
    return np.array([sm.step(i, traj.t[i], traj.q[i], traj.v[i], traj.tau[i]).copy() for i in range(len(traj))])


def test_stream_equals_offline_observer_and_force(arm):
    """Moving samples (no rest detection): τ_ext = −r − b_m and F at tool0 equal the offline observer run
    and `cartesian_force` on the same samples to 1e-10; the flag is the causal crossing test held for
    min_duration; both pushes are flagged and nothing in the contact-free start."""
    traj, dyn, th = arm
    th = dataclasses.replace(th, rest_speed=np.full(len(th.names), np.nan))
    out = _stream(StreamMonitor(dyn, th, frame="tool0"), traj)
    res = MomentumObserver(dyn, gain=th.gain, order=th.order, dt=th.dt).run(traj)
    mt = monitored_torque(dyn, res.r, traj)
    tau = mt.tau_ext - th.bias_move
    t = traj.t - traj.t[0]
    warm = t < th.warmup_s - 1e-9 * th.dt
    assert warm.any() and np.isnan(out[warm, 2:-1]).all() and not out[warm, -1].any()
    np.testing.assert_allclose(out[~warm, 2:8], tau[~warm], rtol=0, atol=1e-10)
    fe = cartesian_force(dyn, traj, MonitoredTorque(np.where(warm[:, None], 0.0, tau), mt.names, mt.rows), "tool0",
                         "local_world_aligned")
    np.testing.assert_allclose(out[~warm, 8:11], fe.F[~warm], rtol=0, atol=1e-10)
    over = (np.abs(mt.tau_ext - th.bias_move) > th.k * th.sigma_move).any(axis=1) & ~warm
    run, want = 0, np.zeros(len(t), bool)
    for i, o in enumerate(over):
        run = run + 1 if o else 0
        want[i] = run and (run - 1) * th.dt >= th.min_duration - 1e-9
    np.testing.assert_array_equal(out[:, -1] > 0, want)
    flag = out[:, -1] > 0
    for p in PUSHES:
        assert flag[(t >= p.start) & (t <= p.end + 0.3)].any()
    assert not flag[t < 3.0].any()


def test_settled_joint_gets_zero_velocity_as_offline(arm):
    """A joint still for the settling time has v := 0 for the observer: the streamed raw torque equals
    the offline run on the log with that joint's v zeroed from then on (1e-10)."""
    traj, dyn, th = arm
    speed = np.full(len(th.names), np.nan)
    speed[1] = 1e3  # shoulder_lift always 'still'
    sm = StreamMonitor(dyn, dataclasses.replace(th, rest_speed=speed))
    raw, settled = [], []
    for i in range(len(traj)):
        sm.step(i, traj.t[i], traj.q[i], traj.v[i], traj.tau[i])
        raw.append(sm.raw.copy())
        settled.append(sm.settled.copy())
    settled = np.array(settled)
    k0 = int(np.ceil(th.settle_s / th.dt - 1e-9))
    assert not settled[:k0, 1].any() and settled[k0:, 1].all() and not settled[:, [0, 2, 3, 4, 5]].any()
    v = traj.v.copy()
    v[k0:, 1] = 0.0
    res = MomentumObserver(dyn, gain=th.gain, order=th.order, dt=th.dt).run(traj.with_(v=v))
    np.testing.assert_allclose(np.array(raw), monitored_torque(dyn, res.r, traj).tau_ext, rtol=0, atol=1e-10)


def test_records_roundtrip_and_bad_records():
    lay = RecordLayout(("a", "b"), ("a", "b"), ("a", "b"), ("fx", "fy", "fz"))
    assert lay.in_bytes == 8 * 8 and lay.n_out == 3 + 2 + 3
    buf = np.zeros(lay.n_in)
    lay.parse_binary(lay.encode_input(7, 0.5, [1, 2], [3, 4], [5, 6], "binary"), 1, buf)
    np.testing.assert_array_equal(buf, [7, 0.5, 1, 2, 3, 4, 5, 6])
    assert lay.parse_csv(lay.encode_input(7, 0.5, [1, 2], [3, 4], [5, 6], "csv"), 1, buf)
    np.testing.assert_array_equal(buf, [7, 0.5, 1, 2, 3, 4, 5, 6])
    assert not lay.parse_csv(b"# comment\n", 1, buf)
    with pytest.raises(DataError, match=r"record 4, field v\[b\]: 'x' is not a number"):
        lay.parse_csv(b"1,0.1,1,2,3,x,5,6\n", 4, buf)
    with pytest.raises(DataError, match=r"record 2: 7 comma-separated fields, expected 8"):
        lay.parse_csv(b"1,0.1,1,2,3,5,6\n", 2, buf)
    with pytest.raises(DataError, match=r"record 3, field t: nan is not finite"):
        lay.parse_binary(lay.encode_input(1, float("nan"), [1, 2], [3, 4], [5, 6], "binary"), 3, buf)
    lay.parse_binary(lay.encode_input(1, 0.1, [1, 2], [3, 4], [float("nan"), 6], "binary"), 3, buf)  # the guard's
    assert np.isnan(buf[6])
    with pytest.raises(DataError, match="record 5: 10 bytes, expected 64"):
        lay.parse_binary(b"0123456789", 5, buf)
    rec = np.array([3, 0.25, 1.5, -2.0, 0.1, 0.2, 0.3, 1.0])
    np.testing.assert_array_equal(lay.decode_output(lay.format_csv(rec), "csv"), rec)
    np.testing.assert_array_equal(lay.decode_output(lay.format_binary(rec), "binary"), rec)


def test_endpoints_refuse_remote_hosts():
    assert parse_endpoint("udp://127.0.0.1:9000", "--input").port == 9000
    assert parse_endpoint("udp://[::1]:9000", "--input").host == "::1"
    with pytest.raises(OptionError, match="not a loopback address.*`allow_remote=True`"):
        parse_endpoint("udp://192.0.2.7:9000", "--input")
    assert parse_endpoint("udp://192.0.2.7:9000", "--input", allow_remote=True).host == "192.0.2.7"
    with pytest.raises(OptionError, match="expected udp://HOST:PORT"):
        parse_endpoint("udp://127.0.0.1", "--input")
    assert parse_endpoint("ros2:joint_states", "--input").topic == "/joint_states"


def test_latency_histogram_quantiles():
    rng = np.random.default_rng(0)
    x = rng.lognormal(np.log(2e-4), 0.8, 20_000)
    h = LatencyHistogram()
    for v in x:
        h.add(float(v))
    for p in (0.5, 0.99, 0.999):
        assert abs(h.quantile(p) / np.quantile(x, p) - 1) < 0.015
    assert h.max == x.max() and h.counts.size == 1802  # fixed, whatever the count


def test_ros2_joint_state_mapping():
    lay = RecordLayout(("j1", "j2"), ("j2",), ("j1", "j2"))
    q, v, tau = joint_state_sample(lay, ["j2", "x", "j1"], [2.0, 9.0, 1.0], [0.2, 9.0, 0.1], [20.0, 9.0, 10.0])
    np.testing.assert_array_equal(q, [1.0, 2.0])
    np.testing.assert_array_equal(v, [0.1, 0.2])
    np.testing.assert_array_equal(tau, [20.0])
    with pytest.raises(DataError, match=r"message 3: no joint\(s\) \['j1'\]"):
        joint_state_sample(lay, ["j2"], [1.0], [1.0], [1.0], 3)
    with pytest.raises(DataError, match="velocity of j2 is nan"):
        joint_state_sample(lay, ["j1", "j2"], [1.0, 1.0], [1.0, float("nan")], [1.0, 1.0])
    assert stamp_seconds(3, 500_000_000) == 3.5
    assert stamp_gap(1.003, 1.001, 1e-3) == 1 and stamp_gap(1.002, 1.001, 1e-3) == 0 and stamp_gap(1.0, None, 1e-3) == 0


# ---- the command (subprocesses: stdin/stdout, signals, UDP) -------------------------------------------------

@pytest.fixture(scope="module")
def cli_setup(arm, tmp_path_factory):
    """The log as npz, `sensorless monitor` thresholds of the UR5 prior on it, and its records as CSV."""
    traj = arm[0]
    work = tmp_path_factory.mktemp("stream")
    write_npz(traj, work / "log.npz")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "OPENBLAS_NUM_THREADS": "1"}
    r = _cli(["monitor", "--robot", "ur5", "--data", str(work / "log.npz"), "--quiet", "0:3", "--out",
              str(work / "mon"), "--no-plot"], env)
    assert r.returncode == 0, r.stderr
    robot = load_robot("ur5")
    lay = RecordLayout(tuple(robot.joint_names), tuple(robot.actuated_joints), tuple(robot.joint_names))
    lines = [lay.encode_input(i, traj.t[i], traj.q[i], traj.v[i], traj.tau[i], "csv") for i in range(len(traj))]
    return work, env, lay, lines


def _cli(args, env, **kw):
    return subprocess.run([sys.executable, "-c", "from sensorless.cli import app; app()", *args], env=env,
                          capture_output=True, **kw)


def _stream_cmd(work, *extra):
    return [sys.executable, "-c", "from sensorless.cli import app; app()", "stream", "--robot", "ur5", "--thresholds",
            str(work / "mon"), "--frame", "tool0", *extra]


def test_cli_stdin_eof_matches_library(cli_setup, arm):
    """CSV on stdin to EOF: exit 0, one estimate per sample equal to the library's, a one-line summary."""
    work, env, lay, lines = cli_setup
    r = subprocess.run(_stream_cmd(work, "--summary", str(work / "sum.json")), input=b"".join(lines), env=env,
                       capture_output=True)
    assert r.returncode == 0, r.stderr.decode()
    rows = [ln for ln in r.stdout.decode().splitlines() if not ln.startswith("#")]
    assert len(rows) == len(lines)
    got = np.array([[float(x) for x in ln.split(",")] for ln in rows])
    from sensorless.cli.applied_model import robot_and_model

    _, art = robot_and_model("ur5", None)
    sm = StreamMonitor(MomentumDynamics(art.structure, art.parameters), StreamThresholds.read(work / "mon"), "tool0")
    np.testing.assert_allclose(got, _stream(sm, arm[0]), rtol=0, atol=1e-10)
    err = r.stderr.decode().strip().splitlines()
    assert len(err) == 1 and f"stream: {len(lines)} samples, 0 dropped" in err[0] and "end of input" in err[0]
    doc = json.loads((work / "sum.json").read_text())
    assert doc["samples"] == len(lines) and doc["dropped"] == 0 and doc["latency"]["p99_us"] > 0


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_cli_signal_stops_cleanly(cli_setup, sig):
    """SIGTERM or SIGINT while waiting for input: exit 0, every sample read was answered, the summary names it."""
    work, env, lay, lines = cli_setup
    p = subprocess.Popen(_stream_cmd(work), stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         env=env)
    p.stdin.write(b"".join(lines[:50]))
    p.stdin.flush()
    out = b""
    deadline = time.time() + 60
    while out.count(b"\n") < 51 and time.time() < deadline:  # header + 50 estimates
        out += os.read(p.stdout.fileno(), 65536)
    p.send_signal(getattr(signal, sig))
    rest, err = p.communicate(timeout=30)
    assert p.returncode == 0, err.decode()
    assert (out + rest).count(b"\n") == 51
    assert "50 samples" in err.decode() and f"stopped by {sig}" in err.decode()


def test_cli_bad_record(cli_setup):
    work, env, lay, lines = cli_setup
    parts = lines[3].split(b",")
    parts[4] = b"oops"
    data = b"".join(lines[:3]) + b",".join(parts) + b"".join(lines[4:10])
    r = subprocess.run(_stream_cmd(work), input=data, env=env, capture_output=True)
    assert r.returncode == 2 and "record 4, field q[elbow_joint]: 'oops' is not a number" in r.stderr.decode()
    r = subprocess.run(_stream_cmd(work, "--skip-bad"), input=data, env=env, capture_output=True)
    assert r.returncode == 0 and "9 samples, 1 dropped" in r.stderr.decode() and "1 bad skipped" in r.stderr.decode()


def test_cli_udp_loopback_no_drops(cli_setup):
    """Binary records over UDP on the loopback (the log replayed 3×, seq and t continued, ~3000 samples):
    every estimate comes back, no sequence gap, the empty datagram ends the stream with exit 0."""
    work, env, lay, lines = cli_setup
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(30)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    p = subprocess.Popen(_stream_cmd(work, "--input", f"udp://127.0.0.1:{port}", "--output",
                                     f"udp://127.0.0.1:{rx.getsockname()[1]}", "--format", "binary"),
                         stderr=subprocess.PIPE, env=env)
    assert "listening" in p.stderr.readline().decode()
    rec = np.zeros(lay.n_in)
    base = [lay.parse_csv(ln, 0, rec) and rec.copy() for ln in lines]
    n_log, dt = len(base), base[1][1] - base[0][1]
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n = 3 * n_log
    for i in range(n):
        b = base[i % n_log]
        tx.sendto(lay.encode_input(i, i * dt, b[2:8], b[8:14], b[14:20], "binary"), ("127.0.0.1", port))
        if i % 200 == 199:
            time.sleep(0.01)
    tx.sendto(b"", ("127.0.0.1", port))
    seqs = set()
    while len(seqs) < n:
        out = np.frombuffer(rx.recv(65536), "<f8")
        assert out.size == lay.n_out + 3  # seq, t, 6 τ_ext, contact and fx, fy, fz
        seqs.add(int(out[0]))
    err = p.communicate(timeout=30)[1].decode()
    assert p.returncode == 0 and seqs == set(range(n)) and f"{n} samples, 0 dropped" in err
    rx.close()
    tx.close()


def test_cli_ros2_input_needs_rclpy(cli_setup):
    try:
        import rclpy  # noqa: F401
        pytest.skip("rclpy is installed: the node itself is exercised by a ROS 2 system")
    except ImportError:
        pass
    work, env, *_ = cli_setup
    r = subprocess.run(_stream_cmd(work, "--input", "ros2:/joint_states"), env=env, capture_output=True)
    assert r.returncode == 2 and "needs a ROS 2 installation with rclpy" in r.stderr.decode()


def test_cli_thresholds_of_another_model_refused(cli_setup, tmp_path):
    work, env, *_ = cli_setup
    doc = json.loads((work / "mon" / "monitor.json").read_text())
    doc["thresholds"]["names"][-1] = "another_joint"
    (tmp_path / "monitor.json").write_text(json.dumps(doc))
    r = _cli(["stream", "--robot", "ur5", "--thresholds", str(tmp_path)], env, input=b"")
    assert r.returncode == 2 and "run `sensorless monitor` with this --model" in r.stderr.decode()


def test_transmission_stream_equals_offline():
    """The dVRK PSM in motor coordinates (a transmission): τ_ext and the force at tool_tip (J G) equal the
    offline observer and `cartesian_force` to 1e-10."""
    import pinocchio as pin

    from sensorless.data.trajectory import Trajectory
    from sensorless.robots.dvrk_psm import psm_structure

    st = psm_structure(drives="motors", coulomb_smoothing=0.05)
    rng = np.random.default_rng(0)
    p = np.zeros(st.n_params)
    pin.seed(0)
    for k in range(st.robot.n_bodies):
        p[10 * k : 10 * k + 10] = pin.Inertia.Random().toDynamicParameters()
    p[st.n_body_params:] = rng.uniform(0.01, 0.2, st.n_params - st.n_body_params)
    dyn = MomentumDynamics(st, p)
    n, N, dt = len(dyn.names), 400, 1e-3
    th = StreamThresholds(tuple(dyn.names), 4.0, np.ones(n), np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n),
                          np.full(n, np.nan), 50.0, 1, 1.0, dt, 0.14, 0.14)
    t = np.arange(N) * dt
    q = 0.3 * np.sin(t[:, None] * np.arange(1, n + 1))
    v = np.gradient(q, dt, axis=0)
    tau = rng.normal(size=(N, n))
    traj = Trajectory(t=t, q=q, v=v, tau=tau, joint_names=tuple(dyn.names))
    out = _stream(StreamMonitor(dyn, th, frame="tool_tip"), traj)
    mt = monitored_torque(dyn, MomentumObserver(dyn, gain=50.0, dt=dt).run(traj).r, traj)
    warm = t < 0.14 - 1e-12
    np.testing.assert_allclose(out[~warm, 2 : 2 + n], mt.tau_ext[~warm], rtol=0, atol=1e-10)
    fe = cartesian_force(dyn, traj, MonitoredTorque(np.where(warm[:, None], 0.0, mt.tau_ext), mt.names, mt.rows),
                         "tool_tip", "local_world_aligned")
    np.testing.assert_allclose(out[~warm, 2 + n : 5 + n], fe.F[~warm], rtol=0, atol=1e-10)


def test_floating_base_model_is_refused():
    solo = load_robot("solo12", floating_base=True)
    st = ModelStructure(solo, joint_terms=("fv", "fc", "armature"))
    dyn = MomentumDynamics(st, st.prior())
    n = len(dyn.names)
    th = StreamThresholds(tuple(dyn.names), 4.0, *(np.ones(n),) * 5, np.full(n, np.nan), 50.0, 1, 1.0, 1e-3, 0.1, 0.1)
    with pytest.raises(OptionError, match="floating-base robot's observer needs the base pose"):
        StreamMonitor(dyn, th)


def test_one_sample_damped_least_squares_equals_batched():
    """The per-sample solver of the stream equals the batched one: regular, near-singular (damped) and
    rank-deficient (NaN on the unobservable component) Jacobians."""
    from sensorless.estimation.force import damped_least_squares, damped_least_squares_one

    rng = np.random.default_rng(0)
    J = rng.normal(size=(30, 3, 6))
    J[10:20, 2] = J[10:20, 0] + 1e-3 * rng.normal(size=(10, 6))  # σ_min below ε: damped
    J[20:, 2] = 0.0  # fz unobservable
    tau = rng.normal(size=(30, 6))
    want = damped_least_squares(J, tau).F
    got = np.array([damped_least_squares_one(J[i], tau[i]) for i in range(30)])
    assert np.isnan(want[20:, 2]).all()
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10, equal_nan=True)


def test_rest_decisions_equal_offline_classification():
    """A joint still from the first sample: the streamed reported torque and contact flag equal
    `classify_at_rest` (the offline decisions) on the same observer output — a step inside the
    static-friction band is a new holding level (no contact), one beyond band + kσ is a contact."""
    from sensorless.estimation.static_band import RestAwareThresholds, classify_at_rest

    robot = load_robot("ur5")
    st = ModelStructure(robot, joint_terms=("armature",))
    dyn = MomentumDynamics(st, st.prior())
    n, N, dt, settle, warm = 6, 3000, 1e-3, 0.05, 0.02
    rng = np.random.default_rng(1)
    t = np.arange(N) * dt
    x = 0.05 * rng.normal(size=(N, n))
    x[1000:, 0] += 0.6  # inside the band (f_s 1.0 around 0): a new stick level
    x[2000:2300, 0] += 2.0  # beyond it: a contact at rest
    x[2500:2600, 3] += 1.0  # a moving joint over k σ_m
    k, band = 4.0, np.full(n, 1.0)
    sig = np.full(n, 0.05)
    th = StreamThresholds(tuple(robot.joint_names), k, sig, sig, np.zeros(n), np.zeros(n), band, np.full(n, 0.01),
                          50.0, 1, 1.0, dt, warm, settle, 0.0)
    sm = StreamMonitor(dyn, th)
    script = iter(-x)

    class Scripted:  # the observer output r = −x, sample by sample
        def step(self, q, v, tau):
            return next(script)

    sm.observer = Scripted()
    v = np.ones((N, n))
    v[:, 0] = 0.0  # joint 0 held still throughout
    out = np.array([sm.step(i, t[i], np.zeros(n), v[i], np.zeros(n)).copy() for i in range(N)])
    rest = np.zeros((N, n), bool)
    rest[:, 0] = True
    off = RestAwareThresholds(list(th.names), k, sig, sig, np.full(n, np.nan), np.zeros(n), np.zeros(n), band,
                              ["given"] * n, np.zeros(n, int), np.zeros(n, int))
    trace = classify_at_rest(x, t, rest, off, quiet=np.zeros(N, bool), warmup=warm, settle=settle)
    np.testing.assert_allclose(out[:, 2:8], trace.tau_ext, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[:, -1] > 0, trace.contact)
    assert not out[1000:2000, -1].any() and out[2000:2300, -1].all() and out[2500:2600, -1].all()

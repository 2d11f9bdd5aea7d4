"""`sensorless stream` cannot be blinded by bad samples (issue #41): non-finite or out-of-range samples are
flagged and kept from the observer, a sender's seq restart re-initialises it at once, tampered threshold
files and wrong units are refused, long lines stay bounded, dropped records give a heartbeat."""

from __future__ import annotations

import io
import json
import os
import select
import subprocess
import sys
import time

import numpy as np
import pytest

from sensorless.data import write_npz
from sensorless.errors import DataError, UnitsError
from sensorless.estimation.momentum import MomentumDynamics
from sensorless.estimation.monitoring import MonitorSettings, monitor_log
from sensorless.realtime import RecordLayout, StreamMonitor, StreamThresholds
from sensorless.realtime.guard import SampleGuard
from sensorless.realtime.transport import Endpoint, Heartbeat, run_stream
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot
from sensorless.testing import NoiseSpec, perturbed_truth
from sensorless_studies.simulation.arm_push import Push, simulate_pushes

PUSHES = [Push(9.0, 9.6, (0.0, 0.0, -30.0), "tool0"), Push(12.5, 13.0, (20.0, -10.0, 0.0), "tool0")]


@pytest.fixture(scope="module")
def arm():
    """A UR5 log of 3001 samples (200 Hz, noisy, two pushes after 9 s), its true model and thresholds."""
    nom = load_robot("ur5")
    truth = perturbed_truth(nom, rng=1)
    traj, gt = simulate_pushes(truth, nom, PUSHES, duration=15.0, seed=3, log_rate=200.0,
                               noise=NoiseSpec(q=1e-4, v=1e-2, tau=0.2))
    dyn = MomentumDynamics(ModelStructure(truth.robot, coulomb_smoothing=gt.coulomb_velocity), truth.parameters())
    mon = monitor_log(dyn, traj, MonitorSettings(quiet="0:3"))
    return traj, dyn, StreamThresholds.from_result(mon)


def _flags(sm: StreamMonitor, traj, tau=None) -> np.ndarray:
    tau = traj.tau if tau is None else tau
    return np.array([sm.step(i, traj.t[i], traj.q[i], traj.v[i], tau[i])[-1] for i in range(len(traj))])


def test_one_huge_torque_flags_only_itself(arm):
    """Reproducer: one τ = 1e300 sample used to poison the observer (2747 of 3000 flagged against 83
    clean). Now the sample is flagged alone and the rest of the stream is flagged exactly as the clean one."""
    traj, dyn, th = arm
    clean = _flags(StreamMonitor(dyn, th), traj)
    assert 0 < clean.sum() < 0.2 * len(traj)
    for bad in (1e300, np.nan, np.inf, -1e300):
        tau = traj.tau.copy()
        tau[1500, 1] = bad
        sm = StreamMonitor(dyn, th)
        got = _flags(sm, traj, tau)
        assert got.sum() <= clean.sum() + 1 and got[1500] == 1.0
        np.testing.assert_array_equal(np.delete(got, 1500)[1600:], np.delete(clean, 1500)[1600:])
        assert sm.rejected == 1 and "tau[shoulder_lift_joint]" in sm.last_rejected


def test_guard_bounds_from_the_model():
    robot = load_robot("ur5")
    g = SampleGuard.for_robot(robot, robot.joint_names, robot.actuated_joints)
    q, v, tau = np.zeros(6), np.zeros(6), np.zeros(6)
    assert g.check(q, v, tau) is None
    q[2] = 9.0  # beyond ±2π (+ margin)
    assert "q[elbow_joint] = 9 is outside" in g.check(q, v, tau)
    assert g.check(np.zeros(6), v, np.full(6, 1e300)).startswith("tau[shoulder_pan_joint]")
    free = SampleGuard.for_robot(None, ("a",), ("a",))  # no limits: the absolute bound only
    assert free.check(np.array([1e3]), np.zeros(1), np.zeros(1)) is None
    assert free.check(np.zeros(1), np.zeros(1), np.array([1e7])) is not None


def test_units_refused_at_start(arm):
    """Reproducers: positions in degrees (1756 of 2000 flagged) and torques ×1000 (1968 flagged) are a
    UnitsError at the first sample, naming the unit, instead of a stream of flags."""
    traj, dyn, th = arm
    with pytest.raises(UnitsError, match="degrees"):
        _flags(StreamMonitor(dyn, th), traj.with_(q=np.degrees(traj.q), v=np.degrees(traj.v)))
    with pytest.raises(UnitsError, match="divided by 1000"):
        _flags(StreamMonitor(dyn, th), traj, traj.tau * 1000)


@pytest.mark.parametrize("key,value", [("k", 1e308), ("warmup_s", 1e300), ("min_duration", 1e9), ("dt", -1.0),
                                       ("gain", float("inf"))])
def test_tampered_thresholds_refused(arm, key, value):
    """Reproducer: `k = 1e308` or `warmup_s = 1e300` in monitor.json silently disabled detection."""
    import dataclasses

    th = arm[2]
    field = {"k": "k", "warmup_s": "warmup_s", "min_duration": "min_duration", "dt": "dt", "gain": "gain"}[key]
    with pytest.raises(DataError, match=f"{field} = .* is outside"):
        dataclasses.replace(th, **{field: value}).validate()


def _run(sm, text: bytes, **kw):
    """run_stream on ``text`` as stdin (CSV), the estimates and stderr lines collected."""
    lines = []
    old_in, old_write = sys.stdin, os.write
    sys.stdin = io.TextIOWrapper(io.BytesIO(text))
    out = []
    os.write = lambda fd, data: (out.append(bytes(data)), len(data))[1] if fd == 1 else old_write(fd, data)
    try:
        stats = run_stream(sm, Endpoint("stdio"), Endpoint("stdio"), "csv",
                           heartbeat=Heartbeat(write=lines.append, clock=iter(range(0, 10**6, 2)).__next__), **kw)
    finally:
        sys.stdin, os.write = old_in, old_write
    return stats, b"".join(out), lines


def _csv(lay, traj, seqs, t=None, tau=None):
    t = traj.t if t is None else t
    tau = traj.tau if tau is None else tau
    return b"".join(lay.encode_input(s, t[i], traj.q[i], traj.v[i], tau[i], "csv") for i, s in enumerate(seqs))


def test_seq_restart_reinitialises_and_warns_at_once(arm):
    """Reproducer: a sender restarting seq at 0 made every later record 'out of order' (skipped), reported
    only by the end summary. Now the record that goes back is answered, the observer restarts (warm-up
    again), and the warning is written when that record is read, before the next one."""
    traj, dyn, th = arm
    sm = StreamMonitor(dyn, th)
    lay = sm.layout
    n = 1500
    seqs = list(range(n)) + list(range(len(traj) - n))
    t = np.concatenate([traj.t[:n], traj.t[n:] - traj.t[n] + traj.t[0]])
    stats, out, err = _run(sm, _csv(lay, traj, seqs, t=t))
    assert stats.samples == len(traj) and stats.restarts == 1 and stats.out_of_order == 0
    warn = [e for e in err if "restarted" in e]
    assert len(warn) == 1 and "seq went back from 1499 to 0" in warn[0] and f"record {n + 1}" in warn[0]
    rows = np.array([[float(x) for x in ln.split(b",")] for ln in out.splitlines() if not ln.startswith(b"#")])
    assert len(rows) == len(traj)
    after = rows[n:]
    warm = after[:, 1] - after[0, 1] < th.warmup_s - 1e-9
    assert warm.any() and np.isnan(after[warm, 2]).all() and np.isfinite(after[~warm, 2]).all()
    # a single reordered record is still out of order, not a restart
    seqs = list(range(100)) + [98] + list(range(100, 200))
    idx = list(range(100)) + [98] + list(range(100, 200))
    sm = StreamMonitor(dyn, th)
    stats, _, err = _run(sm, b"".join(lay.encode_input(s, traj.t[i], traj.q[i], traj.v[i], traj.tau[i], "csv")
                                     for s, i in zip(seqs, idx)))
    assert stats.restarts == 0 and stats.out_of_order == 1 and any("1 out of order" in e for e in err)


def test_heartbeat_and_bounded_lines(arm):
    """A sequence gap and an out-of-range sample each give a heartbeat line on stderr as they happen; a
    10 MB line (reproducer: a 2 GB line took 4.1 GB) is one bad record, never buffered whole."""
    traj, dyn, th = arm
    sm = StreamMonitor(dyn, th)
    lay = sm.layout
    tau = traj.tau.copy()
    tau[150, 0] = 1e300
    seqs = [i for i in range(300) if i != 100]
    text = b"".join(lay.encode_input(i, traj.t[i], traj.q[i], traj.v[i], tau[i], "csv") for i in seqs)
    text = text.replace(b"\n", b"\n" + b"9" * 10_000_000 + b"\n", 1)
    with pytest.raises(DataError, match="record 2: a line longer than"):
        _run(StreamMonitor(dyn, th), text)
    stats, _, err = _run(sm, text, skip_bad=True)
    assert stats.bad == 1 and stats.dropped == 1 and stats.out_of_range == 1 and stats.samples == 299
    assert any("1 dropped" in e for e in err) and any("1 out of range" in e and "tau[" in e for e in err)


@pytest.fixture(scope="module")
def cli_setup(arm, tmp_path_factory):
    traj = arm[0]
    work = tmp_path_factory.mktemp("guard")
    write_npz(traj, work / "log.npz")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "OPENBLAS_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-c", "from sensorless.cli import app; app()", "monitor", "--robot", "ur5",
                        "--data", str(work / "log.npz"), "--quiet", "0:3", "--out", str(work / "mon"), "--no-plot"],
                       env=env, capture_output=True)
    assert r.returncode == 0, r.stderr
    robot = load_robot("ur5")
    lay = RecordLayout(tuple(robot.joint_names), tuple(robot.actuated_joints), tuple(robot.joint_names))
    return work, env, lay


def _stream_cmd(work, *extra):
    return [sys.executable, "-c", "from sensorless.cli import app; app()", "stream", "--robot", "ur5", "--thresholds",
            str(work / "mon"), *extra]


def test_cli_restart_warning_before_end_of_input(cli_setup, arm):
    """The warning reaches stderr while stdin is still open (not in the end summary)."""
    work, env, lay = cli_setup
    traj = arm[0]
    p = subprocess.Popen(_stream_cmd(work), stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         env=env)
    try:
        p.stdin.write(_csv(lay, traj, range(400)))
        p.stdin.write(lay.encode_input(0, traj.t[0], traj.q[0], traj.v[0], traj.tau[0], "csv"))
        p.stdin.flush()
        ready, _, _ = select.select([p.stderr], [], [], 120)
        assert ready
        line = p.stderr.readline().decode()
        assert "seq went back from 399 to 0" in line and "observer re-initialised" in line
    finally:
        p.stdin.close()
        p.wait(timeout=60)
    assert p.returncode == 0


def test_cli_summary_is_a_safe_output(cli_setup, arm, tmp_path):
    """Reproducers: `--summary` overwrote without --force, followed symlinks, blocked on a FIFO and could
    overwrite the thresholds' folder. Now each is refused before the first sample, or replaced atomically."""
    work, env, lay = cli_setup
    data = _csv(lay, arm[0], range(20))
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    link = tmp_path / "sum.json"
    link.symlink_to(victim)
    r = subprocess.run(_stream_cmd(work, "--summary", str(link)), input=data, env=env, capture_output=True)
    assert r.returncode != 0 and "exists" in r.stderr.decode() and victim.read_text() == "keep"
    r = subprocess.run(_stream_cmd(work, "--summary", str(link), "--force"), input=data, env=env, capture_output=True)
    assert r.returncode == 0, r.stderr.decode()
    assert victim.read_text() == "keep" and not link.is_symlink() and json.loads(link.read_text())["samples"] == 20
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    r = subprocess.run(_stream_cmd(work, "--summary", str(fifo), "--force"), input=data, env=env, capture_output=True,
                       timeout=120)
    assert r.returncode != 0 and "FIFO" in r.stderr.decode()
    r = subprocess.run(_stream_cmd(work, "--summary", str(work / "mon" / "monitor.json"), "--force"), input=data,
                       env=env, capture_output=True)
    assert r.returncode != 0 and "input" in r.stderr.decode()
    json.loads((work / "mon" / "monitor.json").read_text())


def test_cli_tampered_threshold_file(cli_setup, arm, tmp_path):
    work, env, lay = cli_setup
    doc = json.loads((work / "mon" / "monitor.json").read_text())
    doc["settings"]["warmup_s"] = 1e300
    (tmp_path / "monitor.json").write_text(json.dumps(doc))
    cmd = _stream_cmd(work)
    cmd[cmd.index(str(work / "mon"))] = str(tmp_path)
    r = subprocess.run(cmd, input=_csv(lay, arm[0], range(5)), env=env, capture_output=True)
    err = r.stderr.decode().strip()
    assert r.returncode != 0 and "warmup_s = 1e+300 is outside [0, 60]" in err and len(err.splitlines()) == 1

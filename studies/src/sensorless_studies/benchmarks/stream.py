"""``sensorless benchmark stream``: a ``sensorless stream`` subprocess fed over UDP on the loopback.

Set-up (all through the CLI, as a user would): a UR5 pushed-arm simulation at the stream's rate
(:func:`~sensorless_studies.simulation.arm_push.simulate_pushes`; a 20 s push-free training log, and a
log of ``samples`` samples pushed at tool0 twice every 10 s after a 10 s contact-free start),
``sensorless identify`` on the training log, ``sensorless monitor --quiet 0:10`` on the pushed
log for the thresholds. Then ``sensorless stream --input udp://127.0.0.1:P --output
udp://127.0.0.1:Q`` runs as a subprocess while this process sends the pushed log's records at
the rate (one datagram each, on a fixed schedule: a late record is sent at once, never skipped)
and a thread receives the estimates.

Reported: samples sent and received, dropped (never received) and the stream's own count of
sequence gaps; latency from just before a record is sent to just after its estimate is received
(one clock, this process), p50/p99/p99.9/max; the stream's processing latency (its summary); its
CPU time (user + system) per sample and as a share of one core; the sender's worst lag behind
its schedule; pushes found and flagged samples outside the pushes; the load average.
"""

from __future__ import annotations

import json
import os
import resource
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["bench_stream"]


def _cli(args: list[str], env: dict) -> None:
    r = subprocess.run([sys.executable, "-c", "from sensorless.__main__ import main; main()", *args], env=env,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"sensorless {' '.join(args)} failed: {r.stderr.strip()[-800:]}")


def _pushes(duration: float, frame: str):
    from ..simulation.arm_push import Push

    out, k = [], 0
    while 16.5 + 10 * k < duration - 0.5:
        out += [Push(12.0 + 10 * k, 12.8 + 10 * k, (0.0, 0.0, -25.0), frame),
                Push(16.0 + 10 * k, 16.5 + 10 * k, (15.0, -10.0, 0.0), frame)]
        k += 1
    return out


def _logs(work: Path, samples: int, rate: float, frame: str, seed: int = 0):
    """Training and pushed logs (npz) in ``work``; returns the pushed log and its pushes."""
    from sensorless.data import write_npz
    from sensorless.robot import load_robot
    from ..simulation.arm_push import simulate_pushes
    from sensorless.testing import NoiseSpec, perturbed_truth

    nom = load_robot("ur5")
    truth = perturbed_truth(nom, rng=seed + 1)
    sim_rate = rate * max(1, int(np.ceil(1000.0 / rate)))
    noise = dict(noise=NoiseSpec(q=1e-4, v=1e-2, tau=0.2), log_rate=rate, sim_rate=sim_rate)
    train, _ = simulate_pushes(truth, nom, [], duration=20.0, seed=seed + 10, base_freq=0.05, **noise)
    duration = (samples - 1) / rate
    pushes = _pushes(duration, frame)
    log, _ = simulate_pushes(truth, nom, pushes, duration=duration, seed=seed + 11, **noise)
    write_npz(train, work / "train.npz")
    write_npz(log, work / "pushed.npz")
    return log, pushes


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bench_stream(samples: int = 100_000, rate: float = 1000.0, fmt: str = "binary", frame: str | None = "tool0",
                 work: Path | None = None, console=None) -> dict:
    """Run the benchmark (module docstring); JSON-able result."""
    from sensorless.realtime.records import RecordLayout

    say = console.print if console is not None else (lambda *a, **k: None)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "OPENBLAS_NUM_THREADS": "1"}
    tmp = None
    if work is None:
        tmp = tempfile.TemporaryDirectory(prefix="sensorless-bench-stream-")
        work = Path(tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        log, pushes = _logs(work, samples, rate, frame or "tool0")
        say(f"simulated {len(log)} samples at {rate:g} Hz in {time.perf_counter() - t0:.1f} s")
        _cli(["identify", "--robot", "ur5", "--data", str(work / "train.npz"), "--out", str(work / "id"), "--no-plot",
              "--force"], env)
        _cli(["monitor", "--robot", "ur5", "--model", str(work / "id"), "--data", str(work / "pushed.npz"), "--quiet",
              "0:10", "--out", str(work / "mon"), "--no-plot", "--force"], env)
        mon = json.loads((work / "mon" / "monitor.json").read_text())
        from sensorless.robot import load_robot

        r = load_robot("ur5")
        layout = RecordLayout(tuple(r.joint_names), tuple(r.actuated_joints), tuple(mon["rows"]),
                              ("fx", "fy", "fz") if frame else ())
        q, v, tau = log.q, log.v, log.tau
        records = [layout.encode_input(i, log.t[i], q[i], v[i], tau[i], fmt) for i in range(len(log))]
        res = _run(records, layout, rate, fmt, frame, work, env, say)
    finally:
        if tmp is not None:
            tmp.cleanup()
    res.update({"samples": len(records), "rate_hz": rate, "format": fmt, "frame": frame, "robot": "ur5",
                "pushes": len(pushes), "python": sys.version.split()[0], "cpus": os.cpu_count()})
    res["detection"] = _detection(res.pop("_flags"), log.t, pushes, 1.0 / rate)
    lat = res["latency_send_to_receive_us"]
    say(f"{res['received']} of {res['samples']} estimates received, {res['dropped']} dropped "
        f"(stream: {res['stream']['dropped']} sequence gaps); send → receive p50 {lat['p50_us']:.0f} µs, p99 "
        f"{lat['p99_us']:.0f} µs, p99.9 {lat['p999_us']:.0f} µs, max {lat['max_us']:.0f} µs; stream CPU "
        f"{res['stream_cpu']['per_sample_us']:.0f} µs/sample ({100 * res['stream_cpu']['core_fraction']:.0f} % of a core); "
        f"load average {res['load_average']['before'][0]:.2f} → {res['load_average']['after'][0]:.2f}")
    return res


def _run(records: list[bytes], layout, rate: float, fmt: str, frame, work: Path, env: dict, say) -> dict:
    from sensorless.realtime.transport import LatencyHistogram

    n = len(records)
    sent = np.full(n, np.nan)
    got = np.full(n, np.nan)
    flags = np.zeros(n, bool)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.2)
    port_in = _free_port()
    cmd = [sys.executable, "-c", "from sensorless.__main__ import main; main()", "stream", "--robot", "ur5", "--model",
           str(work / "id"), "--thresholds", str(work / "mon"), "--input", f"udp://127.0.0.1:{port_in}", "--output",
           f"udp://127.0.0.1:{rx.getsockname()[1]}", "--format", fmt, "--summary", str(work / "stream.json")]
    if frame:
        cmd += ["--frame", frame]
    done = threading.Event()
    stats = {"received": 0, "duplicates": 0}

    def receive() -> None:
        buf = bytearray(65536)
        while not done.is_set():
            try:
                k = rx.recv_into(buf)
            except socket.timeout:
                continue
            now = time.perf_counter()
            rec = layout.decode_output(bytes(buf[:k]), fmt)
            i = int(rec[0])
            if 0 <= i < n and np.isnan(got[i]):
                got[i] = now
                flags[i] = rec[-1] > 0
                stats["received"] += 1
            else:
                stats["duplicates"] += 1

    load0 = os.getloadavg()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
    line = proc.stderr.readline()
    if "listening" not in line:
        proc.wait()
        raise RuntimeError(f"sensorless stream did not start: {line}{proc.stderr.read()[-800:]}")
    cpu_start = _proc_cpu(proc.pid)
    th = threading.Thread(target=receive, daemon=True)
    th.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx.connect(("127.0.0.1", port_in))
    period = 1.0 / rate
    say(f"sending {n} records at {rate:g} Hz ({n * period:.0f} s)")
    clock, sleep = time.perf_counter, time.sleep
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)  # the receiver's timestamps wait at most this for the interpreter
    start = clock() + 0.05
    lag = 0.0
    t_start = clock()
    for i, data in enumerate(records):
        target = start + i * period
        now = clock()
        if target > now:  # sleep, never spin: the receiving thread needs the GIL at once
            sleep(target - now)
            now = clock()
        lag = max(lag, now - target)
        sent[i] = now
        tx.send(data)
    wall = clock() - t_start
    time.sleep(0.2)  # the last estimates
    cpu_stream = _proc_cpu(proc.pid) - cpu_start
    tx.send(b"")  # end of stream
    sys.setswitchinterval(switch)
    err = proc.stderr.read()
    proc.stderr.close()
    proc.wait(timeout=60)
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    time.sleep(0.3)
    done.set()
    th.join()
    tx.close()
    rx.close()
    if proc.returncode != 0:
        raise RuntimeError(f"sensorless stream exited {proc.returncode}: {err[-800:]}")
    hist = LatencyHistogram()
    ok = ~np.isnan(got)
    lat = got[ok] - sent[ok]
    for x in lat:
        hist.add(float(x))
    cpu_total = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    summary = json.loads((work / "stream.json").read_text())
    return {
        "received": int(ok.sum()), "dropped": int(n - ok.sum()), "duplicates": stats["duplicates"],
        "latency_send_to_receive_us": {**hist.summary(), "mean_us": float(lat.mean() * 1e6) if lat.size else None,
                                       "exact_p99_us": float(np.percentile(lat, 99) * 1e6) if lat.size else None,
                                       "exact_p999_us": float(np.percentile(lat, 99.9) * 1e6) if lat.size else None},
        "over_1ms": int((lat > 1e-3).sum()), "over_10ms": int((lat > 1e-2).sum()),
        "stream": {k: summary[k] for k in ("samples", "dropped", "out_of_order", "bad_skipped", "contact_samples",
                                           "stopped_by", "latency", "observer_step")},
        "stream_stderr": err.strip().splitlines()[-1] if err.strip() else "",
        "stream_cpu": {"streaming_seconds": cpu_stream, "per_sample_us": 1e6 * cpu_stream / n,
                       "core_fraction": cpu_stream / wall, "process_seconds": cpu_total,
                       "start_up_seconds": cpu_total - cpu_stream},
        "send_wall_s": wall, "sender_max_lag_us": lag * 1e6,
        "load_average": {"before": list(load0), "after": list(os.getloadavg())},
        "_flags": flags,
    }


def _proc_cpu(pid: int) -> float:
    """User + system CPU seconds of a running process (Linux /proc; NaN elsewhere)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _detection(flags: np.ndarray, t: np.ndarray, pushes, dt: float) -> dict:
    """Pushes with a flagged sample inside [start, end + 0.3 s]; flagged samples more than 0.5 s from any push."""
    t = np.asarray(t) - t[0]
    found = sum(bool(flags[(t >= p.start) & (t <= p.end + 0.3)].any()) for p in pushes)
    near = np.zeros(len(t), bool)
    for p in pushes:
        near |= (t >= p.start - 0.5) & (t <= p.end + 0.5)
    return {"pushes_found": int(found), "pushes": len(pushes), "flagged_samples": int(flags.sum()),
            "flagged_outside_pushes": int((flags & ~near).sum())}

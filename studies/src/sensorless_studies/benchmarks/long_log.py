"""`sensorless benchmark long-log`: `sensorless identify` on long UR5 logs, as a user runs it.

For each size a UR5 log (5 harmonics at 0.1 Hz, 1 kHz, torque noise 0.1 N·m; t, q, dq, tau in an
``.npz``) is written, and ``sensorless identify --robot ur5 --data LOG --out DIR`` (the defaults:
LMI, γ by cross-validation, plots) runs as a fresh subprocess of this Python with the same
``sys.path``. Recorded per run: the wall time from process start to exit, the peak resident memory
of that process (GNU time's ``%M``), µs per sample (wall / N) and, between the two sizes,
the marginal µs per sample ((wall_big − wall_small) / (N_big − N_small): the per-sample cost
without the fixed start-up, solve and plot costs). In the same run, the bare C++ regressor (the
kernel of :mod:`~sensorless.regressor.native`) over the log's own states gives the per-sample
reference. The load average is recorded before and after: the machine may be shared.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["bench_long_log", "bare_kernel_us"]

GOALS = {"per_sample_over_bare_cpp_at_largest": "<= 3", "peak_memory_ratio_largest_over_smallest": "<= 1.2"}


def write_ur5_log(path: Path, n: int, seed: int = 0, accelerations: bool = False) -> Path:
    """The UR5 benchmark log of :func:`~sensorless_studies.benchmarks.speed.fourier_log` as t, q, dq, tau
    (and the simulated ddq with ``accelerations``)."""
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, streamed_fourier_log

    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=seed)
    parts = list(streamed_fourier_log(truth, random_fourier(robot, rng=seed + 1, base_freq=0.1), rate=1000.0,
                                      n_samples=n, noise_std=0.1, rng=seed))
    cat = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    np.savez(path, t=cat("t"), q=cat("q"), dq=cat("v"), tau=cat("tau"), **({"ddq": cat("a")} if accelerations else {}))
    return path


def bare_kernel_us(log_path: Path, n: int = 200_000, chunk: int = 2048, repeats: int = 3) -> "float | None":
    """µs per sample of the C++ regressor kernel alone over the first ``n`` states of the log (best of
    ``repeats``); None when the kernel is not built."""
    from sensorless.regressor import native
    from sensorless.robot import load_robot

    robot = load_robot("ur5")
    kernel = native.native_regressor(robot.model)
    if kernel is None:
        return None
    with np.load(log_path) as z:
        Q, V = z["q"][:n], z["dq"][:n]
    A = np.gradient(V, axis=0) * 1000.0
    rows = np.arange(robot.nv)
    out = np.empty((chunk, robot.nv, kernel.n_body_params))
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for s in range(0, len(Q), chunk):
            e = min(s + chunk, len(Q))
            kernel(Q[s:e], V[s:e], A[s:e], rows, out[: e - s])
        best = min(best, time.perf_counter() - t)
    return 1e6 * best / len(Q)


def _run(args: list[str], env: dict) -> tuple[float, float]:
    """(wall seconds, peak RSS MiB) of ``sensorless ARGS`` in a fresh process. The peak is GNU time's
    ``%M`` when /usr/bin/time exists (its child is forked from a small process), else ``os.wait4``'s
    (which on Linux also counts this process's memory at the fork)."""
    cmd = [sys.executable, "-c", "from sensorless.__main__ import main; main()", *args]
    timer = Path("/usr/bin/time")
    t = time.perf_counter()
    if timer.exists():
        r = subprocess.run([str(timer), "-f", "%M", *cmd], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True)
        wall = time.perf_counter() - t
        if r.returncode != 0:
            raise RuntimeError(f"sensorless {' '.join(args)} failed ({r.returncode}): {r.stderr.strip()[-800:]}")
        return wall, int(r.stderr.strip().splitlines()[-1]) / 1024.0
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t
    err = p.stderr.read().decode(errors="replace")
    p.stderr.close()
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise RuntimeError(f"sensorless {' '.join(args)} failed ({p.returncode}): {err.strip()[-800:]}")
    return wall, usage.ru_maxrss / 1024.0


def bench_long_log(sizes: list[int], *, repeats: int = 1, extra_args: tuple[str, ...] = (), work: "Path | None" = None,
                   console=None) -> dict:
    """Runs of ``sensorless identify`` on UR5 logs of ``sizes`` samples (module docstring)."""
    from sensorless.io import versions

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    load_before = os.getloadavg()
    runs = []
    with tempfile.TemporaryDirectory(dir=work) as tmp:
        tmp = Path(tmp)
        bare = None
        for n in sorted(sizes):
            log = write_ur5_log(tmp / f"ur5_{n}.npz", n)
            if bare is None:
                bare = bare_kernel_us(log)
            walls, rss = [], []
            for _ in range(repeats):
                w, m = _run(["identify", "--robot", "ur5", "--data", str(log), "--out", str(tmp / f"out_{n}"),
                             "--force", *extra_args], env)
                walls.append(w)
                rss.append(m)
            from sensorless.identification.artifact import read_result

            doc = read_result(tmp / f"out_{n}")
            run = {"n_samples": n, "wall_seconds": min(walls), "wall_seconds_all": walls, "peak_rss_mib": max(rss),
                   "per_sample_us": 1e6 * min(walls) / n, "streamed": doc["settings"].get("streamed") is not None,
                   "gamma": doc["diagnostics"].get("gamma"),
                   "consistent": (doc["diagnostics"].get("lmi") or {}).get("consistent")}
            if bare:
                run["per_sample_over_bare_cpp"] = run["per_sample_us"] / bare
            runs.append(run)
            if console is not None:
                console.print(f"N={n:>9,d}: {run['wall_seconds']:.2f} s, {run['per_sample_us']:.2f} µs/sample, "
                              f"peak RSS {run['peak_rss_mib']:.0f} MiB, streamed {run['streamed']}")
            (tmp / f"ur5_{n}.npz").unlink()
    small, big = runs[0], runs[-1]
    res = {
        "benchmark": "long-log",
        "command": "sensorless identify --robot ur5 --data LOG --out DIR --force " + " ".join(extra_args),
        "bare_cpp_regressor_us": bare,
        "runs": runs,
        "peak_memory_ratio_largest_over_smallest": big["peak_rss_mib"] / small["peak_rss_mib"],
        "goals": GOALS,
        "load_average_before": load_before, "load_average_after": os.getloadavg(),
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()},
        "versions": versions(),
    }
    if len(runs) > 1:
        marginal = 1e6 * (big["wall_seconds"] - small["wall_seconds"]) / (big["n_samples"] - small["n_samples"])
        res["marginal_per_sample_us"] = marginal
        if bare:
            res["marginal_per_sample_over_bare_cpp"] = marginal / bare
    if console is not None:
        console.print(f"bare C++ regressor {bare if bare is None else f'{bare:.2f}'} µs/sample; memory ratio "
                      f"{res['peak_memory_ratio_largest_over_smallest']:.2f}; marginal "
                      f"{res.get('marginal_per_sample_us', float('nan')):.2f} µs/sample")
    return res

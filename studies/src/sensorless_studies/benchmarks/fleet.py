"""`sensorless benchmark dask`: fleet-scale identification on a Dask LocalCluster vs one process.

For each total sample count N, ``N / samples_per_file`` Parquet logs (``t``, ``q_*``,
``tau_*``; v and v̇ come from the Savitzky–Golay step of the preprocessing, as for a
real log; :func:`~sensorless_studies.simulation.fleet_logs.write_fleet_logs`) are written to a temporary directory, then identified twice from the same files:

* single process: the unchanged CLI path (``load_logs`` + :func:`identify`), run in a
  fresh process so its peak RSS is its own, with one BLAS thread like the Dask workers;
* Dask: :func:`identify_files` on a fresh ``LocalCluster`` (``workers`` processes, one
  thread each).

Peak memory is each process's resident high-water mark (``VmHWM``), reset to the current
RSS (``/proc/self/clear_refs``) after imports and before the timed run; the idle RSS at
that moment is reported next to it. Both paths import their modules before timing.

Reported: wall times, speed-up, CPU seconds of the single process and of each worker
(their ratio is the speed-up the cluster gives when every worker has a free core, which
wall times on a loaded machine do not show), relative difference of the identified parameters, peak
memory per worker at each N (flat in N: a worker holds one file and O(rows·p²) sums), and
the machine load (``os.getloadavg``) at start and end. The files are deleted afterwards.

Data are cheap to make: the excitation is a Fourier series with an integer number of
samples per period, so the RNEA torques (Pinocchio, true model + friction) are computed
for one period and tiled; each file gets its own seeded noise.
"""

from __future__ import annotations

import contextlib
import os
import platform
import shutil
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

__all__ = ["bench_dask"]

PANDA_LOCK = ("panda_finger_joint1", "panda_finger_joint2")


def _lock(robot_name: str) -> tuple[str, ...]:
    return PANDA_LOCK if robot_name == "panda" else ()


def _warm_up() -> None:
    """Import what reading a log needs, so neither path times its imports."""
    import pyarrow.parquet  # noqa: F401

    from sensorless.cli import common  # noqa: F401
    from sensorless.regressor import distributed  # noqa: F401


def _status_mb(key: str) -> float:
    """A memory figure of this process from /proc/self/status (Linux) [MiB]."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")  # pragma: no cover


def _hwm_mb() -> float:
    """Peak resident memory (VmHWM) [MiB]."""
    return _status_mb("VmHWM")


def _reset_peak() -> float:
    """Reset VmHWM to the current RSS (``/proc/self/clear_refs`` ← 5) and return that RSS [MiB]."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:  # pragma: no cover - not Linux / not permitted: the peak then includes start-up
        pass
    return _status_mb("VmRSS")


#: What Dask's nanny sets in every worker (distributed.nanny.pre-spawn-environ); the single
#: process gets the same, else a multi-threaded BLAS on the small per-chunk products makes it
#: many times slower on a loaded machine and the comparison measures that instead.
_ONE_BLAS_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


@contextlib.contextmanager
def _environ(values: dict):
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _single_process(robot_name: str, files: list[str], method: str) -> dict:
    """The CLI's local path, in a fresh process: load every log, then identify."""
    from sensorless.run.logs import load_logs
    from sensorless.identification import identify
    from sensorless.regressor import ModelStructure
    from sensorless.robot import load_robot

    _warm_up()
    robot = load_robot(robot_name, lock_joints=_lock(robot_name))
    structure = ModelStructure(robot)
    idle = _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    logs = load_logs(files, robot, None, None, None, None, 1)
    res = identify(structure, logs, method=method)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_seconds": wall, "cpu_seconds": cpu, "params": res.base_values, "idle_rss_mb": idle,
            "peak_rss_mb": _hwm_mb()}


def _worker_start() -> float:
    _warm_up()
    return _reset_peak()


def _dask_run(robot_name: str, files: list[str], method: str, workers: int) -> dict:
    import logging

    from distributed import Client, LocalCluster

    from sensorless.identification import identify_files
    from sensorless.regressor import ModelStructure
    from sensorless.robot import load_robot

    structure = ModelStructure(load_robot(robot_name, lock_joints=_lock(robot_name)))
    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        startup = time.perf_counter() - t0
        idle = client.run(_worker_start)  # imports, then reset each worker's peak-RSS counter
        cpu0 = client.run(time.process_time)
        t1 = time.perf_counter()
        res = identify_files(structure, files, client=client, method=method)
        wall = time.perf_counter() - t1
        cpu1 = client.run(time.process_time)
        peak = client.run(_hwm_mb)
    return {
        "wall_seconds": wall,
        "cluster_startup_seconds": startup,
        "params": res.base_values,
        "n_samples": res.diagnostics["n_samples"],
        "rank": res.base.rank,
        "worker_cpu_seconds": [cpu1[w] - cpu0[w] for w in sorted(cpu1)],
        "worker_peak_rss_mb": [peak[w] for w in sorted(peak)],
        "worker_idle_rss_mb": [idle[w] for w in sorted(idle)],
    }


def bench_dask(
    robot_name: str = "panda",
    sizes: tuple[int, ...] = (1_000_000, 10_000_000),
    samples_per_file: int = 100_000,
    workers: int = 2,
    method: str = "ols",
    console=None,
    seed: int = 0,
    tmp_root: str | None = None,
) -> dict:
    """Run the benchmark described in the module docstring; returns a JSON-able dict."""
    from sensorless.io import versions
    from sensorless.robot import load_robot
    from ..simulation.fleet_logs import write_fleet_logs

    robot = load_robot(robot_name, lock_joints=_lock(robot_name))
    load_start = os.getloadavg()
    runs = []
    for n in sizes:
        n_files = max(n // samples_per_file, 1)
        tmp = Path(tempfile.mkdtemp(prefix="sensorless-dask-bench-", dir=tmp_root))
        try:
            tg = time.perf_counter()
            paths = write_fleet_logs(robot, tmp, n_files, samples_per_file, seed=seed, subdirs=4)
            gen = time.perf_counter() - tg
            files = [str(p) for p in paths]
            size_mb = sum(p.stat().st_size for p in paths) / 2**20
            with _environ(_ONE_BLAS_THREAD), ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
                single = pool.submit(_single_process, robot_name, files, method).result()
            dask = _dask_run(robot_name, files, method, workers)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        p1, p2 = single.pop("params"), dask.pop("params")
        run = {
            "n_samples": n_files * samples_per_file,
            "n_files": n_files,
            "samples_per_file": samples_per_file,
            "parquet_mb": size_mb,
            "generation_seconds": gen,
            "single_process": single,
            "dask": dask,
            "speedup": single["wall_seconds"] / dask["wall_seconds"],
            "speedup_including_cluster_startup": single["wall_seconds"]
            / (dask["wall_seconds"] + dask["cluster_startup_seconds"]),
            "params_relative_difference": float(np.linalg.norm(p1 - p2) / np.linalg.norm(p1)),
            # on a loaded machine wall times measure the other processes too; CPU seconds do not:
            # single-process CPU ÷ busiest worker's CPU is the speed-up with a free core per worker
            "speedup_from_cpu_seconds": single["cpu_seconds"] / max(dask["worker_cpu_seconds"]),
        }
        runs.append(run)
        if console is not None:
            console.print(
                f"N={run['n_samples']:>10,d} ({n_files} files): single process {single['wall_seconds']:.1f} s "
                f"(peak {single['peak_rss_mb']:.0f} MiB), Dask {workers} workers {dask['wall_seconds']:.1f} s "
                f"(+{dask['cluster_startup_seconds']:.1f} s start-up) → {run['speedup']:.2f}× (CPU-time ratio "
                f"{run['speedup_from_cpu_seconds']:.2f}×); worker peak RSS "
                f"{', '.join(f'{m:.0f}' for m in dask['worker_peak_rss_mb'])} MiB; |Δπ|/|π| = {run['params_relative_difference']:.1e}"
            )
    peaks = [max(r["dask"]["worker_peak_rss_mb"]) for r in runs]
    return {
        "benchmark": "dask",
        "robot": robot_name,
        "method": method,
        "workers": workers,
        "threads_per_worker": 1,
        "blas_threads_both_paths": _ONE_BLAS_THREAD,
        "runs": runs,
        "worker_peak_rss_ratio_largest_over_smallest_N": max(peaks) / min(peaks),
        "goals": {"params_relative_difference": "<= 1e-10", "worker_peak_memory": "flat in N"},
        "load_average_1_5_15min": {"start": list(load_start), "end": list(os.getloadavg())},
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()},
        "versions": {**versions(), **_dask_versions()},
    }


def _dask_versions() -> dict:
    try:
        import dask
        import distributed

        return {"dask": dask.__version__, "distributed": distributed.__version__}
    except ImportError:  # pragma: no cover
        return {}

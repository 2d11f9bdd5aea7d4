"""Benchmarks run through the CLI (`sensorless benchmark …`); each returns a JSON-able dict.

identify: stream N synthetic samples of a 7-DoF arm through the compressed identification.
Reports wall time, the time of the compression alone (data generation excluded), the
per-sample cost divided by the cost of a bare ``computeJointTorqueRegressor`` call timed
in the same run, and peak traced memory (tracemalloc, in a second untimed run) of the
whole identification including the streamed data chunks.
"""

from __future__ import annotations

import platform
import time
import tracemalloc

import numpy as np
import pinocchio as pin

from .excitation import random_fourier
from .identification import identify
from .identification.result import versions
from .regressor import ModelStructure
from .robot import load_robot
from .simulation import perturbed_truth, streamed_fourier_log

__all__ = ["bench_identify", "bare_regressor_cost"]


def bare_regressor_cost(robot, n: int = 20000, seed: int = 0) -> float:
    """Seconds per bare Pinocchio joint-torque-regressor call (random states, best of 3)."""
    rng = np.random.default_rng(seed)
    m, d = robot.model, robot.data
    Q = np.array([pin.randomConfiguration(m) for _ in range(256)])
    V, A = rng.normal(size=(256, m.nv)), rng.normal(size=(256, m.nv))
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        for i in range(n):
            k = i & 255
            pin.computeJointTorqueRegressor(m, d, Q[k], V[k], A[k])
        best = min(best, (time.perf_counter() - t) / n)
    return best


class _TimedSource:
    """Wraps a chunk generator and accumulates the time spent generating data."""

    def __init__(self, gen):
        self.gen, self.seconds = gen, 0.0

    def __iter__(self):
        while True:
            t = time.perf_counter()
            try:
                item = next(self.gen)
            except StopIteration:
                self.seconds += time.perf_counter() - t
                return
            self.seconds += time.perf_counter() - t
            yield item


def bench_identify(robot_name: str, sizes: list[int], console=None, seed: int = 0) -> dict:
    lock = ["panda_finger_joint1", "panda_finger_joint2"] if robot_name == "panda" else ()
    robot = load_robot(robot_name, lock_joints=lock)
    truth = perturbed_truth(robot, rng=seed)
    fourier = random_fourier(robot, rng=seed + 1, base_freq=0.05)
    structure = ModelStructure(robot)
    bare = bare_regressor_cost(robot)
    runs = []
    for n in sizes:
        def source():
            return _TimedSource(streamed_fourier_log(truth, fourier, rate=1000.0, n_samples=n, noise_std=0.1, rng=seed))

        src = source()
        t0 = time.perf_counter()
        res = identify(structure, iter(src))
        wall = time.perf_counter() - t0
        # memory in a second, identical run: tracemalloc slows allocation, so it is not timed
        tracemalloc.start()
        identify(structure, iter(source()))
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        compress_only = res.diagnostics["compress_seconds"] - src.seconds
        run = {
            "n_samples": n,
            "wall_seconds": wall,
            "data_generation_seconds": src.seconds,
            "compression_seconds": compress_only,
            "solve_seconds": res.diagnostics["solve_seconds"],
            "per_sample_us": 1e6 * compress_only / n,
            "per_sample_over_bare_regressor": compress_only / n / bare,
            "peak_traced_memory_mb": peak / 2**20,
            "rank": res.base.rank,
        }
        runs.append(run)
        if console is not None:
            console.print(
                f"N={n:>9,d}: wall {wall:7.2f} s, compression {run['per_sample_us']:.2f} µs/sample "
                f"= {run['per_sample_over_bare_regressor']:.2f}× bare regressor, peak {run['peak_traced_memory_mb']:.1f} MiB"
            )
    peaks = [r["peak_traced_memory_mb"] for r in runs]
    return {
        "benchmark": "identify",
        "robot": robot_name,
        "n_params": structure.n_params,
        "bare_regressor_us": 1e6 * bare,
        "runs": runs,
        "peak_memory_ratio_largest_over_smallest": max(peaks) / min(peaks),
        "goals": {"per_sample_over_bare_regressor": "<= 2", "peak_memory_ratio": "<= 1.10"},
        "machine": {"cpu_count": __import__("os").cpu_count(), "platform": platform.platform()},
        "versions": versions(),
        "chunk": 10_000,
    }

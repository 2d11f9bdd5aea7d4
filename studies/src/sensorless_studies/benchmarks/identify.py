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

from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.io import versions
from sensorless.regressor import ModelStructure
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, streamed_fourier_log

__all__ = ["bench_identify", "bare_regressor_cost", "contact_log"]


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


FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


def contact_log(robot, structure, n: int, seed: int):
    """Random Solo12 states: first half all four feet in contact (stance), second half trot pairs."""
    from sensorless.data.trajectory import Trajectory
    from sensorless.identification.base import random_states

    rng = np.random.default_rng(seed)
    Q, V, A = random_states(structure, n, rng)
    flags = np.ones((n, 4), bool)
    half = n // 2
    flags[half::2, [1, 2]] = False
    flags[half + 1 :: 2, [0, 3]] = False
    qi = [robot.q_index(j) for j in robot.joint_names]
    vi = [robot.v_index(j) for j in robot.joint_names]
    return Trajectory(t=np.arange(n) * 0.01, q=Q[:, qi], v=V[:, vi], a=A[:, vi], tau=rng.normal(size=(n, 12)),
                      base_q=Q[:, :7], base_v=V[:, :6], base_a=A[:, :6], joint_names=robot.joint_names,
                      extras={"contact": flags}, source="<benchmark>")


def bench_contact(n_samples: int = 100_000, seed: int = 0, console=None, methods=("svd", "lmi")) -> dict:
    """Contact-projected identification of Solo12 from stance/trot samples.

    End-to-end wall time (Jacobians + projection + regressor + compression + solve) per
    method, and the per-sample cost of the projector: batched (this library) vs a per-sample
    Python loop with ``numpy.linalg.pinv`` on the same Jacobians, timed in the same run.
    """
    from sensorless.regressor import ContactStructure, compress

    robot = load_robot("solo12")
    structure = ContactStructure(robot, contact_frames=FEET)
    log = contact_log(robot, structure, n_samples, seed)
    t0 = time.perf_counter()
    ne = compress(structure, log, chunk=256)
    t_compress = time.perf_counter() - t0
    solves = {}
    for m in methods:
        t1 = time.perf_counter()
        identify(structure, ne, method=m)
        solves[m] = time.perf_counter() - t1
    # projector alone, on a 20 000-sample subset with both contact patterns
    sub = log.take(np.r_[0:10_000, n_samples // 2 : n_samples // 2 + 10_000] if n_samples >= 40_000 else slice(None))
    Q, _, _ = structure.state(sub)
    flags = structure.contacts(sub)
    from sensorless.regressor.contact_kinematics import contact_jacobians, null_space_projector

    groups = []  # (pattern rows, Jacobians of the active contacts) per contact pattern
    tj = time.perf_counter()
    for pattern in np.unique(flags, axis=0):
        idx = np.flatnonzero((flags == pattern).all(axis=1))
        on = np.flatnonzero(pattern)
        fids = [structure._fids[i] for i in on]
        groups.append(contact_jacobians(robot, fids, [3] * len(on), Q[idx], np.ones((len(idx), len(on)), bool)))
    t_jac = time.perf_counter() - tj
    tb = time.perf_counter()
    for J in groups:
        for s in range(0, len(J), 1024):
            null_space_projector(J[s : s + 1024], structure.rcond)
    t_batched = time.perf_counter() - tb
    tl = time.perf_counter()
    eye = np.eye(robot.nv)
    for J in groups:
        for Ji in J:
            eye - np.linalg.pinv(Ji) @ Ji
    t_loop = time.perf_counter() - tl
    n_sub = len(sub)
    res = {
        "benchmark": "contact",
        "robot": "solo12",
        "n_samples": n_samples,
        "contact_patterns": "50 % all four feet, 50 % trot diagonal pairs",
        "n_params": structure.n_params,
        "compression_seconds": t_compress,
        "solve_seconds": solves,
        "end_to_end_seconds": {m: t_compress + t for m, t in solves.items()},
        "per_sample_us": {
            "end_to_end_compression": 1e6 * t_compress / n_samples,
            "contact_jacobians_pinocchio": 1e6 * t_jac / n_sub,
            "projector_batched": 1e6 * t_batched / n_sub,
            "projector_numpy_pinv_loop": 1e6 * t_loop / n_sub,
        },
        "speedup_projector_vs_pinv_loop": t_loop / t_batched,
        "goal": "batched projector >= 10x faster than a per-sample numpy pinv loop on the same Jacobians",
        "versions": versions(),
    }
    if console is not None:
        p = res["per_sample_us"]
        console.print(
            f"Solo12, {n_samples:,d} samples: compression {t_compress:.2f} s, solves {solves}; projector "
            f"{p['projector_batched']:.2f} µs/sample vs pinv loop {p['projector_numpy_pinv_loop']:.2f} µs/sample "
            f"→ {res['speedup_projector_vs_pinv_loop']:.1f}× (Jacobians {p['contact_jacobians_pinocchio']:.2f} µs/sample)"
        )
    return res

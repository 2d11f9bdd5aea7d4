"""Speed at the limit and CLI latency (issue 13 items 3–4), run through ``sensorless benchmark speed``.

Every ratio is measured in the same run, interleaved and best-of-``repeats``, because the machine
may be shared (its load average is recorded before and after):

* compression µs/sample of an in-memory log vs a bare Python ``pin.computeJointTorqueRegressor``
  loop over the same states (goal ≤ 1.3×), with and without the overlap thread, with the C++
  kernel (:mod:`~sensorless.regressor.native`, when built) and with the pure-Python loop; and
  vs the kernel alone over the same states;
* peak traced memory of a streamed identification at each size in ``memory_sizes`` (goal: flat);
* the batched contact projector (C++ kernel when built, and the NumPy route) vs a per-sample
  ``numpy.linalg.pinv`` loop on the same Solo12 Jacobians, interleaved (goal ≥ 15×), and contact
  compression with the null-space fold vs the 18-row projector;
* ``sensorless --help`` wall time interleaved with ``python -c pass`` (best, median and their ratio;
  goal ≤ 0.3 s) and a ``sensorless identify`` call on a UR5 log end to end (goal < 2.5 s), as
  subprocesses of this Python with the same ``sys.path``.
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

__all__ = ["bench_speed", "fourier_log"]

GOALS = {
    "compression_over_bare_regressor": "<= 1.3",
    "peak_memory_ratio_largest_over_smallest": "<= 1.10",
    "projector_speedup_vs_pinv_loop": ">= 15",
    "help_seconds": "<= 0.3",
    "identify_cli_seconds": "< 2.5",
}


def fourier_log(robot, n: int, seed: int = 0):
    """An in-memory n-sample synthetic log (UR5-style: 5 harmonics at 0.1 Hz, 1 kHz, noise 0.1 N·m)."""
    from sensorless.data.trajectory import Trajectory
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, streamed_fourier_log

    truth = perturbed_truth(robot, rng=seed)
    parts = list(streamed_fourier_log(truth, random_fourier(robot, rng=seed + 1, base_freq=0.1), rate=1000.0,
                                      n_samples=n, noise_std=0.1, rng=seed))
    cat = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    return Trajectory(t=cat("t"), q=cat("q"), v=cat("v"), a=cat("a"), tau=cat("tau"),
                      joint_names=parts[0].joint_names, source=f"<benchmark {robot.name}>")


def _best(fns: dict, repeats: int) -> dict:
    """Best wall time of each callable, the callables interleaved ``repeats`` times."""
    best = dict.fromkeys(fns, np.inf)
    for _ in range(repeats):
        for k, f in fns.items():
            t = time.perf_counter()
            f()
            best[k] = min(best[k], time.perf_counter() - t)
    return best


def bench_compression(robot_name: str, n: int, repeats: int) -> dict:
    """Compression µs/sample with the C++ kernel (when built) and with the pure-Python loop, each with
    and without the overlap thread, against a bare Python regressor loop and the kernel alone."""
    import pinocchio as pin

    from sensorless.regressor import ModelStructure, compress, native
    from sensorless.robot import load_robot

    lock = ["panda_finger_joint1", "panda_finger_joint2"] if robot_name == "panda" else ()
    robot = load_robot(robot_name, lock_joints=lock)
    log = fourier_log(robot, n)
    s = ModelStructure(robot)
    Q, V, A = s.state(log)
    m, d, f = robot.model, robot.data, pin.computeJointTorqueRegressor
    kernel = native.native_regressor(m)

    def bare():
        for i in range(n):
            f(m, d, Q[i], V[i], A[i])

    def python_path(overlap):
        def run():
            os.environ["SENSORLESS_NATIVE"] = "0"
            native._lib.cache_clear()
            try:
                compress(s, log, overlap=overlap)
            finally:
                os.environ.pop("SENSORLESS_NATIVE")
                native._lib.cache_clear()
        return run

    fns = {"bare": bare, "python_overlap": python_path(True), "python_sequential": python_path(False)}
    if kernel is not None:
        buf = np.empty((2048, s.n_rows, s.n_body_params))
        rows = np.arange(m.nv)

        def cxx():
            for i in range(0, n, 2048):
                kernel(Q[i:i + 2048], V[i:i + 2048], A[i:i + 2048], rows, buf[: len(Q[i:i + 2048])])

        fns.update(native=cxx, overlap=lambda: compress(s, log, overlap=True),
                   sequential=lambda: compress(s, log, overlap=False))
    best = _best(fns, repeats)
    us = {k: 1e6 * v / n for k, v in best.items()}
    paths = [k for k in ("overlap", "sequential", "python_overlap", "python_sequential") if k in us]
    out = {
        "robot": robot_name, "n_samples": n, "n_params": s.n_params, "rows": s.n_rows,
        "bare_regressor_us": us["bare"], "compiled_kernel": kernel is not None,
        "compression_us": {k: us[k] for k in paths},
        "compression_over_bare_regressor": {k: us[k] / us["bare"] for k in paths},
        "best_of": repeats,
    }
    if kernel is not None:
        out["native_regressor_us"] = us["native"]
        out["compression_over_native_regressor"] = {k: us[k] / us["native"] for k in paths}
    return out


def bench_memory(robot_name: str, sizes: list[int]) -> dict:
    from .identify import bench_identify

    res = bench_identify(robot_name, sizes)
    keep = ("n_samples", "wall_seconds", "compression_seconds", "per_sample_us", "peak_traced_memory_mb")
    return {"robot": robot_name, "runs": [{k: r[k] for k in keep} for r in res["runs"]],
            "peak_memory_ratio_largest_over_smallest": res["peak_memory_ratio_largest_over_smallest"]}


def bench_contact_speed(n: int, n_compress: int, repeats: int) -> dict:
    """The batched projector (the C++ kernel when built, and the NumPy route) and the null-space basis vs a
    per-sample ``numpy.linalg.pinv`` loop on the same Solo12 Jacobians, interleaved best-of-``repeats`` (the
    pinv loop too), and the contact compression with the null-space fold vs the 18-row projector fold."""
    from .identify import FEET, contact_log
    from sensorless.regressor import ContactStructure, compress, native
    from sensorless.regressor.contact_kinematics import contact_jacobians, null_space_basis, null_space_projector
    from sensorless.robot import load_robot

    robot = load_robot("solo12")
    s = ContactStructure(robot, contact_frames=FEET)
    log = contact_log(robot, s, n, seed=0)
    Q, _, _ = s.state(log)
    flags = s.contacts(log)
    groups = []
    t = time.perf_counter()
    for pattern in np.unique(flags, axis=0):
        idx = np.flatnonzero((flags == pattern).all(axis=1))
        on = np.flatnonzero(pattern)
        groups.append(contact_jacobians(robot, [s._fids[i] for i in on], [3] * len(on), Q[idx],
                                        np.ones((len(idx), len(on)), bool)))
    jacobian_seconds = time.perf_counter() - t
    eye = np.eye(robot.nv)
    compiled = native.contact_projector() is not None

    def batched(fn, numpy_route=False):
        def run():
            if numpy_route:
                os.environ["SENSORLESS_NATIVE"] = "0"
                native._lib.cache_clear()
            try:
                for J in groups:
                    for a in range(0, len(J), 2048):
                        fn(J[a : a + 2048], s.rcond)
            finally:
                if numpy_route:
                    os.environ.pop("SENSORLESS_NATIVE")
                    native._lib.cache_clear()
        return run

    def pinv_loop():
        for J in groups:
            for Ji in J:
                eye - np.linalg.pinv(Ji) @ Ji

    fns = {"projector": batched(null_space_projector), "basis": batched(null_space_basis), "pinv_loop": pinv_loop}
    if compiled:
        fns["projector_numpy"] = batched(null_space_projector, numpy_route=True)
    best = _best(fns, repeats)
    sub = log.take(np.r_[0 : n_compress // 2, n // 2 : n // 2 + n_compress // 2])
    proj = ContactStructure(robot, contact_frames=FEET, fold_basis="projector")
    comp = _best({"nullspace": lambda: compress(s, sub), "projector": lambda: compress(proj, sub)}, max(1, repeats - 1))
    exact = np.concatenate([null_space_basis(J, s.rcond)[1] for J in groups])
    us = {k: 1e6 * v / n for k, v in best.items()}
    out = {
        "robot": "solo12", "n_samples": n, "contact_patterns": "50 % all four feet, 50 % trot diagonal pairs",
        "projector_route": "C++ kernel" if compiled else "NumPy",
        "projector_batched_us": us["projector"],
        "null_space_basis_us": us["basis"],
        "pinv_loop_us": us["pinv_loop"],
        "projector_speedup_vs_pinv_loop": best["pinv_loop"] / best["projector"],
        "basis_speedup_vs_pinv_loop": best["pinv_loop"] / best["basis"],
        "basis_exact_fraction": float(exact.mean()),
        "contact_jacobians_us": 1e6 * jacobian_seconds / n,
        "best_of": repeats,
        "compression": {"n_samples": len(sub), "nullspace_us": 1e6 * comp["nullspace"] / len(sub),
                        "projector_us": 1e6 * comp["projector"] / len(sub),
                        "speedup": comp["projector"] / comp["nullspace"]},
    }
    if compiled:
        out["projector_numpy_us"] = us["projector_numpy"]
        out["projector_numpy_speedup_vs_pinv_loop"] = best["pinv_loop"] / best["projector_numpy"]
    return out


def _cli(args: list[str], env: dict) -> float:
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", "from sensorless.__main__ import main; main()", *args], env=env,
                       capture_output=True, text=True)
    dt = time.perf_counter() - t
    if r.returncode != 0:
        raise RuntimeError(f"sensorless {' '.join(args)} failed: {r.stderr.strip()[-500:]}")
    return dt


def _stats(times: list[float]) -> dict:
    return {"best": min(times), "median": float(np.median(times))}


def bench_startup(runs: int, env: dict) -> dict:
    """``sensorless --help`` and ``python -c pass`` as subprocesses, interleaved ``runs`` times (after one
    warm-up of each): best and median wall time of each and their ratios, so a loaded machine shows as a
    slower ``python -c pass`` rather than a slower CLI. The console script next to this Python is used when
    present (what a user types), else ``python -c "from sensorless.__main__ import main; main()"``."""
    import importlib.util

    import sensorless.cli

    script = Path(sys.executable).with_name("sensorless")
    help_cmd = ([str(script), "--help"] if script.exists()
                else [sys.executable, "-c", "from sensorless.__main__ import main; main()", "--help"])
    cmds = {"help": help_cmd, "python_pass": [sys.executable, "-c", "pass"]}
    times: dict[str, list[float]] = {k: [] for k in cmds}
    for k in range(runs + 1):
        for name, cmd in cmds.items():
            t = time.perf_counter()
            r = subprocess.run(cmd, env=env, capture_output=True, text=True)
            dt = time.perf_counter() - t
            if r.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr.strip()[-500:]}")
            if k:  # the first round warms the file cache
                times[name].append(dt)
    h, p = _stats(times["help"]), _stats(times["python_pass"])
    cached = importlib.util.cache_from_source(sensorless.cli.__file__)
    return {
        "command": "sensorless --help" if script.exists() else "python -c 'from sensorless.__main__ import main; main()' --help",
        "help_seconds": h, "python_pass_seconds": p,
        "help_over_python_pass": {"best": h["best"] / p["best"], "median": h["median"] / p["median"]},
        "runs": runs, "bytecode_cached": os.path.exists(cached),
    }


def bench_cli(n_identify: int, repeats: int, parts=("startup", "identify")) -> dict:
    from sensorless.data.readers import write_npz
    from sensorless.robot import load_robot

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    res: dict = {}
    if "startup" in parts:
        res["startup"] = bench_startup(max(10, repeats), env)
        res["help_seconds"] = res["startup"]["help_seconds"]
    if "identify" not in parts:
        return res
    out: dict = {"identify_cli_seconds": {"plot": [], "no_plot": []}}
    with tempfile.TemporaryDirectory() as tmp:
        log = write_npz(fourier_log(load_robot("ur5"), n_identify), Path(tmp) / "ur5.npz")
        for k in range(repeats):
            for key, extra in (("plot", []), ("no_plot", ["--no-plot"])):
                out["identify_cli_seconds"][key].append(_cli(
                    ["identify", "--robot", "ur5", "--data", str(log), "--out", str(Path(tmp) / f"o{k}{key}"), *extra], env))
    return {
        **res,
        "n_samples_identify": n_identify,
        "command": f"sensorless identify --robot ur5 --data <{n_identify}-sample npz> --out DIR [--no-plot]",
        "identify_cli_seconds": {k: _stats(v) for k, v in out["identify_cli_seconds"].items()},
        "runs": repeats,
    }


#: The parts of the benchmark, in the order they run (``bench_speed(parts=...)``, ``--parts``).
PARTS = ("compression", "memory", "contact", "startup", "identify")


def bench_speed(*, n_compress: int = 100_000, memory_sizes=(100_000, 1_000_000), n_contact: int = 100_000,
                n_identify: int = 100_000, repeats: int = 3, parts=PARTS, console=None) -> dict:
    """All figures of the speed benchmark as one JSON-able dict (see the module docstring); ``parts``: a
    subset of :data:`PARTS`."""
    from sensorless.io import versions

    def say(msg):
        if console is not None:
            console.print(msg, highlight=False)

    load0 = os.getloadavg()
    res: dict = {"benchmark": "speed", "goals": GOALS, "parts": [p for p in PARTS if p in parts]}
    if "compression" in parts:
        res["compression"] = [bench_compression(r, n_compress, repeats) for r in ("ur5", "panda")]
        for c in res["compression"]:
            ratio = c["compression_over_bare_regressor"]
            say(f"compression {c['robot']} (µs/sample; bare Python regressor {c['bare_regressor_us']:.2f}"
                + (f", C++ kernel alone {c['native_regressor_us']:.2f}" if c["compiled_kernel"] else "") + "): "
                + ", ".join(f"{k} {v:.2f} ({ratio[k]:.2f}×)" for k, v in c["compression_us"].items()))
    if "memory" in parts:
        res["memory"] = bench_memory("ur5", list(memory_sizes))
        say(f"peak memory {[round(r['peak_traced_memory_mb'], 1) for r in res['memory']['runs']]} MiB at "
            f"{list(memory_sizes)} samples (ratio {res['memory']['peak_memory_ratio_largest_over_smallest']:.3f})")
    if "contact" in parts:
        res["contact"] = c = bench_contact_speed(n_contact, min(n_contact, 20_000), repeats)
        numpy_route = (f" (NumPy route {c['projector_numpy_us']:.2f} µs, {c['projector_numpy_speedup_vs_pinv_loop']:.1f}×)"
                       if "projector_numpy_us" in c else "")
        say(f"contact projector ({c['projector_route']}) {c['projector_batched_us']:.2f} µs/sample vs pinv loop "
            f"{c['pinv_loop_us']:.1f} → {c['projector_speedup_vs_pinv_loop']:.1f}×{numpy_route}; null-space basis "
            f"{c['null_space_basis_us']:.2f} µs; contact "
            f"compression {c['compression']['nullspace_us']:.1f} µs (null space) vs {c['compression']['projector_us']:.1f} (projector)")
    if "startup" in parts or "identify" in parts:
        res["cli"] = cl = bench_cli(n_identify, repeats, parts)
        if "startup" in cl:
            st = cl["startup"]
            say(f"`{st['command']}` {st['help_seconds']['best']:.3f} s best, {st['help_seconds']['median']:.3f} s median "
                f"of {st['runs']}; `python -c pass` {st['python_pass_seconds']['best']:.3f} / "
                f"{st['python_pass_seconds']['median']:.3f} s (ratio {st['help_over_python_pass']['best']:.1f}× best, "
                f"{st['help_over_python_pass']['median']:.1f}× median)")
        if "identify_cli_seconds" in cl:
            say(f"identify {n_identify} samples: {cl['identify_cli_seconds']['plot']['best']:.2f} s (plot), "
                f"{cl['identify_cli_seconds']['no_plot']['best']:.2f} s (--no-plot)")
    from sensorless.regressor import native

    res["machine"] = {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                      "load_average_1_5_15min": {"start": list(load0), "end": list(os.getloadavg())},
                      "blas_threads": 1, "compiled_kernel": native.available()}
    res["versions"] = versions()
    return res

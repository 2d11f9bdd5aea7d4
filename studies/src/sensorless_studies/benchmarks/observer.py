"""``sensorless benchmark observer``: the momentum observer's cost per sample, compiled and in Python.

Per robot (UR5; Solo12 with a floating base; dVRK PSM in motor coordinates, a transmission with
drive friction, springs and motor inertias), on a model with every friction term non-zero and random
states (positions within the limits, velocities over five decades):

* ``step``: :meth:`~sensorless.estimation.MomentumObserver.step` from Python, compiled (C++ kernel), each
  call timed with ``perf_counter_ns``: mean, p50, p99, p99.9, max and steps over 1 ms;
* ``step_into`` (no allocation) and ``kernel_loop`` (the kernel's step in a C++ loop: no Python);
* ``bare_cpp``: Pinocchio's ``crba``, ``computeCoriolisMatrix`` (then Cᵀv) and
  ``computeGeneralizedGravity`` over the same Pinocchio states, in a C++ loop;
* ``ratio``: step / bare_cpp mean per round, the rounds interleaving the two over blocks of states
  (the machine is shared: one round's load hits both); the median over rounds, and the ratio of the p50s;
* ``python_step``: the Python step (``compiled=False``) on fewer samples; ``run_us`` the offline
  :meth:`~sensorless.estimation.MomentumObserver.run` per sample;
* the load average before and after.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

__all__ = ["ROBOTS", "observer_cases", "run"]

ROBOTS = ("ur5", "solo12", "dvrk_psm")


def observer_cases(seed: int = 0) -> dict:
    """{robot: MomentumDynamics} with the model's inertias (random bodies for the PSM) and every joint or
    drive term set to a seeded value in [0.05, 0.5]."""
    import pinocchio as pin

    from sensorless.estimation.momentum import MomentumDynamics
    from sensorless.regressor.terms import ModelStructure
    from sensorless.robot import load_robot
    from sensorless.robots.dvrk_psm import psm_structure

    rng = np.random.default_rng(seed)
    out = {}
    ur5 = load_robot("ur5")
    structs = {
        "ur5": ModelStructure(ur5, joint_terms=("fv", "fc", "stribeck", "offset", "armature"), coulomb_smoothing=0.05,
                              rest_velocity={j: 1e-3 for j in ur5.actuated_joints}),
        "solo12": ModelStructure(load_robot("solo12", floating_base=True), joint_terms=("fv", "fc", "offset", "armature"),
                                 coulomb_smoothing=0.02),
        "dvrk_psm": psm_structure(drives="motors", coulomb_smoothing=0.02),
    }
    for name, st in structs.items():
        p = st.prior() if not st.drives else np.zeros(st.n_params)
        if st.drives:
            for k in range(st.robot.n_bodies):
                p[10 * k: 10 * k + 10] = pin.Inertia.Random().toDynamicParameters()
        p[st.n_body_params:] = rng.uniform(0.05, 0.5, st.n_params - st.n_body_params)
        out[name] = MomentumDynamics(st, p)
    return out


def _stats(ns: np.ndarray) -> dict:
    us = np.asarray(ns, dtype=float) / 1e3
    return {"mean_us": float(us.mean()), "p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)),
            "p999_us": float(np.percentile(us, 99.9)), "max_us": float(us.max()), "over_1ms": int((us > 1000).sum()),
            "samples": int(us.size)}


def _timed(fn, args, ns: np.ndarray, lo: int, hi: int) -> None:
    clock = time.perf_counter_ns
    for i in range(lo, hi):
        t0 = clock()
        fn(*args[i])
        ns[i] = clock() - t0


def _robot(dyn, samples: int, python_samples: int, rounds: int, rng: np.random.Generator) -> dict:
    from sensorless.data.trajectory import Trajectory
    from sensorless.estimation.momentum import MomentumObserver
    from sensorless.estimation.native_observer import random_states

    q, v, tau, bq, bv = random_states(dyn, samples, rng)
    args = list(zip(q, v, tau, bq, bv))
    res: dict = {"n": dyn.n}
    slow = MomentumObserver(dyn, gain=50.0, dt=1e-3, compiled=False)
    m = min(python_samples, samples)
    ns = np.empty(m)
    _timed(slow.step, args, ns, 0, m)
    res["python_step"] = _stats(ns)
    res["python_step_us"] = res["python_step"]["mean_us"]
    robot = dyn.structure.robot  # a transmission's: its coordinates
    full = np.zeros((m, len(robot.joint_names)))
    full[:, [robot.joint_names.index(j) for j in robot.actuated_joints]] = tau[:m]
    traj = Trajectory(t=np.arange(m) * 1e-3, q=q[:m], v=v[:m], tau=full, joint_names=list(robot.joint_names),
                      base_q=None if bq[0] is None else np.asarray(bq[:m]),
                      base_v=None if bv[0] is None else np.asarray(bv[:m]))
    t0 = time.perf_counter()
    MomentumObserver(dyn, gain=50.0).run(traj)
    res["run_us"] = (time.perf_counter() - t0) / m * 1e6
    fast = MomentumObserver(dyn, gain=50.0, dt=1e-3)
    kernel = fast.prepare()
    res["compiled"], res["reason"] = kernel is not None, fast.compiled_reason
    if kernel is None:
        res["step_us"] = res["python_step_us"]
        return res
    into = MomentumObserver(dyn, gain=50.0, dt=1e-3)
    loop = MomentumObserver(dyn, gain=50.0, dt=1e-3).prepare()
    out = np.empty(dyn.n)
    into_args = [(out, *a) for a in args]
    IN = kernel.inputs(q, v, tau, None if bq[0] is None else np.asarray(bq), None if bv[0] is None else np.asarray(bv))
    Qt, Vt = kernel.tree_states(IN)
    step_ns, into_ns, bare_ns, loop_ns = (np.empty(samples) for _ in range(4))
    ratios = []
    edges = np.linspace(0, samples, rounds + 1).astype(int)
    for lo, hi in zip(edges[:-1], edges[1:]):
        bare_ns[lo:hi] = kernel.bare(Qt[lo:hi], Vt[lo:hi])[0]
        _timed(fast.step, args, step_ns, lo, hi)
        _timed(into.step_into, into_args, into_ns, lo, hi)
        loop_ns[lo:hi] = loop.run(IN[lo:hi], timed=True)[3]
        ratios.append(step_ns[lo:hi].mean() / bare_ns[lo:hi].mean())
    res["step"], res["step_into"] = _stats(step_ns), _stats(into_ns)
    res["kernel_loop"], res["bare_cpp"] = _stats(loop_ns), _stats(bare_ns)
    res["step_us"] = res["step"]["mean_us"]
    res["ratio"] = float(np.median(ratios))
    res["ratio_rounds"] = [float(r) for r in ratios]
    res["ratio_p50"] = res["step"]["p50_us"] / res["bare_cpp"]["p50_us"]
    res["speedup_vs_python"] = res["python_step"]["p50_us"] / res["step"]["p50_us"]
    return res


def run(samples: int = 100_000, python_samples: int = 2000, rounds: int = 100, seed: int = 0,
        robots=ROBOTS) -> dict:
    """The benchmark (module docstring) as a JSON-able dict."""
    import pinocchio as pin

    from sensorless.estimation.native_observer import available
    from sensorless.regressor import native

    load0 = os.getloadavg()
    cases = observer_cases(seed)
    rng = np.random.default_rng(seed + 1)
    out = {"samples": samples, "python_samples": python_samples, "rounds": rounds, "seed": seed,
           "python": platform.python_version(), "pinocchio": pin.__version__, "cpus": os.cpu_count(),
           "kernel": str(native.library_path()) if available() else None,
           "kernel_reason": None if available() else native.unavailable_reason() or "built before the observer step",
           "timer": "time.perf_counter_ns around each call (about 0.1 µs of it is the timer)",
           "load_average_before": list(load0), "robots": {}}
    for name in robots:
        out["robots"][name] = _robot(cases[name], samples, python_samples, rounds, rng)
    out["load_average_after"] = list(os.getloadavg())
    return out

"""Benchmark of the physically consistent solver on compressed data.

For each robot, normal equations are built from random states (all nv rows, so a
floating base is included): ``y = W π_true + noise`` with π_true from
:func:`~sensorless_studies.simulation.perturbed_truth` and 3 % noise per row. Then, per
solver, the conic program is built and solved once, timing

* ``setup_seconds``: building the program (data factor, constraints, regulariser)
  plus cvxpy's compilation to the solver's standard form,
* ``solve_seconds``: the conic solver itself (and cvxpy's unpacking),

with the status and the per-body consistency of the result. Ellipsoids (which may
load collision meshes) are computed once per robot and timed separately.
"""

from __future__ import annotations

import platform
import time
from typing import Sequence

import numpy as np

from sensorless.errors import SensorlessError
from sensorless.regressor.normal_equations import NormalEquations
from sensorless.regressor.terms import ModelStructure
from sensorless.robot import Robot, load_robot
from sensorless.testing import perturbed_truth
from sensorless.identification.base import random_states
from sensorless.identification.ellipsoids import resolve_ellipsoids
from sensorless.identification.lmi import build_lmi

__all__ = ["bench_lmi", "random_state_equations"]


def random_state_equations(
    structure: ModelStructure,
    params: np.ndarray,
    *,
    n_samples: int = 200,
    noise: float = 0.03,
    rng: np.random.Generator | int = 0,
) -> NormalEquations:
    """Normal equations of ``n_samples`` random states with ``y = W params + ε``,
    ``ε_r ~ N(0, (noise · RMS(y_r))²)`` per row."""
    rng = np.random.default_rng(rng)
    Q, V, A = random_states(structure, n_samples, rng)
    W = structure.evaluate(Q, V, A)
    y = W @ params
    y = y + rng.normal(size=y.shape) * noise * np.sqrt((y**2).mean(axis=0))
    ne = NormalEquations.zeros(structure.n_rows, structure.n_params)
    ne.add(W, y)
    return ne


def bench_lmi(
    robots: Sequence[str | Robot] = ("solo12", "talos"),
    solvers: Sequence[str] = ("CLARABEL", "SCS"),
    *,
    regularization: str = "pullback",
    gamma: float = 1e-3,
    n_samples: int = 200,
    seed: int = 0,
) -> dict:
    """``{"settings": ..., "results": {robot: {"n_bodies", "n_params", "ellipsoid_seconds",
    "solvers": {solver: {status, setup_seconds, solve_seconds, consistent, projected, ...}}}}}``.

    A failing solver is reported with ``status = "error: ..."`` instead of raising.
    """
    out: dict = {
        "settings": {
            "regularization": regularization,
            "gamma": gamma,
            "n_samples": n_samples,
            "seed": seed,
            "machine": platform.machine(),
            "python": platform.python_version(),
        },
        "results": {},
    }
    for spec in robots:
        robot = spec if isinstance(spec, Robot) else load_robot(spec)
        structure = ModelStructure(robot)
        truth = perturbed_truth(robot, rng=seed)
        ne = random_state_equations(structure, truth.parameters(structure.joint_terms), n_samples=n_samples, rng=seed)
        t0 = time.perf_counter()
        ell = resolve_ellipsoids(robot, None, prior=structure.prior())
        t_ell = time.perf_counter() - t0
        entry: dict = {
            "n_bodies": robot.n_bodies,
            "n_params": structure.n_params,
            "n_rows": structure.n_rows,
            "floating_base": robot.floating_base,
            "ellipsoid_seconds": t_ell,
            "solvers": {},
        }
        for solver in solvers:
            try:
                prob = build_lmi(ne, structure, regularization=regularization, ellipsoids=ell or False)
                sol = prob.solve(gamma, solver=solver)
                entry["solvers"][solver] = {
                    "status": sol.status,
                    "setup_seconds": sol.setup_seconds,
                    "solve_seconds": sol.solve_seconds,
                    "total_seconds": sol.setup_seconds + sol.solve_seconds,
                    "consistent": sol.consistent,
                    "projected": sol.projected,
                    "relative_residual": sol.relative_residual,
                    "data_rank": sol.settings["data_rank"],
                }
            except (SensorlessError, ValueError) as exc:
                entry["solvers"][solver] = {"status": f"error: {exc}"}
        out["results"][robot.name] = entry
    return out

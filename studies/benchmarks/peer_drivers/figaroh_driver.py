"""figaroh 1.0.2 physical fit of the `sensorless benchmark peers` case, run by figaroh's own venv python.

    PYTHON figaroh_driver.py CASE.npz OUT.npz

CASE (written by sensorless_studies.benchmarks.peer_runs): ``urdf``, ``body_names``, training ``q``, ``v``, ``a``,
``tau``. The fit is figaroh's ``select_stage: physical_fit`` estimator
(``figaroh.identification.physical_fit.build_problem`` + ``solve_direct_effort_fit``: least squares on
the joint-torque regressor with a pseudo-inertia LMI per link, Tikhonov weight 1e-6 towards the URDF
prior, figaroh's default cvxopt solver through picos). OUT: ``params`` (10 per body, Pinocchio order
m, mc, Ixx Ixy Iyy Ixz Iyz Izz about the joint frame) and ``info`` (JSON). No sensorless import.
"""

import sys
import time

import numpy as np
from figaroh.identification.physical_fit import build_problem, solve_direct_effort_fit
from peer_case import load_case, write_result

KEYS = ["m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz"]  # figaroh's names, Pinocchio's order


def main(case_path, out_path):
    c, model, bodies, jids, Y = load_case(case_path)
    tau = c["tau"]
    cols = np.concatenate([np.arange(10 * (j - 1), 10 * j) for j in jids])
    names = [f"{key}_{b}" for b in bodies for key in KEYS]
    prior = np.concatenate([model.inertias[j].toDynamicParameters() for j in jids])
    t0 = time.perf_counter()
    problem = build_problem(Y[:, cols], tau.reshape(-1), names, bodies, prior=prior)
    record = solve_direct_effort_fit(problem)
    solve = time.perf_counter() - t0
    if record.theta is None:
        raise SystemExit(f"figaroh physical fit failed: {record.solver_status} {record.exception}")
    info = {"estimator": "figaroh.identification.physical_fit.solve_direct_effort_fit", "solver": record.solver,
            "status": record.solver_status, "accepted": bool(record.accepted), "fit_seconds": solve}
    write_result(out_path, np.asarray(record.theta, dtype=float), info)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])

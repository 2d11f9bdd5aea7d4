"""rigeo 0.2.0 box-realisable fit of the `sensorless benchmark peers` case, run by rigeo's own venv python.

    PYTHON rigeo_driver.py CASE.npz OUT.npz

CASE (written by sensorless_studies.benchmarks.peer_runs): ``urdf``, ``body_names``, training ``q``, ``v``, ``a``,
``tau``, and per body a bounding box in its joint frame (``box_center``, ``box_half_extents``: the
axis-aligned box of the link's collision meshes, joint origins and the URDF body's equivalent uniform
box in any orientation). The fit is rigeo's constrained
least squares (min ½/N ‖Yθ − τ‖², no regulariser; on the QR-reduced rows, the same minimiser) with, per body, the pseudo-inertia ``J ⪰ 0``
(``rigeo.pim_psd``) and density realisability on the box (``rigeo.Box.moment_sdp_constraints``),
solved by cvxpy with Clarabel (MOSEK needs a licence). The regressor is Pinocchio's (rigeo ships
none). OUT: ``params`` (10 per body, Pinocchio order) and ``info`` (JSON). No sensorless import.
"""

import sys
import time

import cvxpy as cp
import numpy as np
import rigeo as rg
from peer_case import load_case, write_result

PIN_TO_RIGEO = [0, 1, 2, 3, 4, 5, 7, 6, 8, 9]  # Pinocchio ..Iyy, Ixz.. -> rigeo ..Ixz, Iyy.. (its own inverse)


def main(case_path, out_path):
    c, model, bodies, jids, Y = load_case(case_path)
    tau = c["tau"]
    cols = np.concatenate([np.arange(10 * (j - 1), 10 * j)[PIN_TO_RIGEO] for j in jids])
    t0 = time.perf_counter()
    Q, A = np.linalg.qr(Y[:, cols])  # ‖Yθ − τ‖² = ‖Rθ − Qᵀτ‖² + const: Clarabel ends 'optimal_inaccurate' on the full rows
    b = Q.T @ tau.reshape(-1)
    thetas = [cp.Variable(10) for _ in bodies]
    constraints = []
    for k, th in enumerate(thetas):
        J = rg.pim_must_equal_vec(th)
        box = rg.Box(half_extents=c["box_half_extents"][k], center=c["box_center"][k])
        constraints += rg.pim_psd(J) + box.moment_sdp_constraints(J)
    cost = 0.5 / Y.shape[0] * cp.sum_squares(A @ cp.hstack(thetas) - b)
    problem = cp.Problem(cp.Minimize(cost), constraints)
    problem.solve(solver=cp.CLARABEL)
    solve = time.perf_counter() - t0
    if problem.status != "optimal":
        raise SystemExit(f"rigeo box fit: solver status {problem.status}")
    params = np.concatenate([th.value[PIN_TO_RIGEO] for th in thetas])
    info = {"estimator": "least squares + rigeo.pim_psd + rigeo.Box.moment_sdp_constraints", "solver": "CLARABEL",
            "status": problem.status, "fit_seconds": solve}
    write_result(out_path, params, info)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])

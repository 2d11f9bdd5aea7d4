"""Acceptance study: floating-base mass and CoM from foot wrenches with a constant bias.

A perturbed 'true' robot (``perturbed_truth``: masses ±20 %, CoMs ±2 cm) walks (double
and single support alternating, 6-D sole wrenches solving the floating-base dynamics,
:func:`~sensorless_studies.simulation.wrench_log.wrench_log`); no joint torques are logged. The
measured wrenches carry a constant 30 N horizontal force bias. The nominal model is
identified from the 6 base rows (``contact_rows="base"``, OLS, closest to the model file)
with each wrench-offset model, and the total mass and the CoM (base frame, neutral
configuration) are compared with the truth.

    python -m sensorless_studies.experiments.wrench_bias [robot] [out.json]
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import pinocchio as pin

from sensorless.identification import identify
from sensorless.identification.floating_base import base_wrench_metrics, com_cop_check, com_positions
from sensorless.regressor.contact import ContactStructure
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth
from ..simulation.wrench_log import walking_flags, wrench_log

__all__ = ["run"]

FEET = ("left_sole_link", "right_sole_link")
CASES = {
    "left sole +x 30 N (sole frame)": (np.array([[30.0, 0, 0], [0, 0, 0]]), "sole"),
    "both feet +x 30 N (world)": (np.array([[30.0, 0, 0], [30.0, 0, 0]]), "world"),
}


def run(robot: str = "talos", duration: float = 20.0, rate: float = 100.0, noise: float = 2.0, seed: int = 0) -> dict:
    nominal = load_robot(robot)
    truth = perturbed_truth(nominal, rng=seed).robot
    Q0 = pin.neutral(nominal.model)[None]
    pi_true = truth.inertial_parameters()
    m_true, c_true = pi_true.reshape(-1, 10)[:, 0].sum(), com_positions(truth, pi_true, Q0)[0]
    n = int(round(duration * rate))
    out = {"robot": robot, "duration_s": duration, "rate_hz": rate, "wrench_noise_std": noise, "seed": seed,
           "true_mass": float(m_true), "model_file_mass": float(nominal.inertial_parameters().reshape(-1, 10)[:, 0].sum()),
           "cases": {}}
    for name, (bias, frame) in CASES.items():
        log = wrench_log(truth, FEET, duration=duration, rate=rate, flags=walking_flags(n, 2, int(0.8 * rate)),
                         bias=bias, bias_frame=frame, noise=noise, seed=seed + 1)
        rows = {}
        for offset in ("none", "net", "foot", "sole"):
            s = ContactStructure(nominal, contact_frames=FEET, contact_dims=(6, 6), mode="wrench",
                                 contact_rows="base", wrench_offset=offset, joint_terms=())
            t0 = time.perf_counter()
            res = identify(s, log)
            m = float(res.inertial_parameters.reshape(-1, 10)[:, 0].sum())
            c = com_positions(nominal, res.inertial_parameters, Q0)[0]
            rows[offset] = {
                "mass_error_percent": 100 * (m - m_true) / m_true,
                "com_error_mm": 1e3 * float(np.linalg.norm(c - c_true)),
                "offsets": s.offset_values(res.parameters),
                "base_wrench_rmse_N": base_wrench_metrics(s, res.parameters, log)["force_rmse_norm"],
                "com_cop_mm": 1e3 * com_cop_check(s, res.parameters, log)["distance_mean"],
                "seconds": time.perf_counter() - t0,
            }
        out["cases"][name] = rows
    return out


if __name__ == "__main__":
    res = run(sys.argv[1] if len(sys.argv) > 1 else "talos")
    for case, rows in res["cases"].items():
        print(f"{res['robot']}: {case}")
        for off, r in rows.items():
            print(f"  offset {off:5s}: mass {r['mass_error_percent']:+.3f} %, CoM {r['com_error_mm']:.2f} mm, "
                  f"CoM–CoP {r['com_cop_mm']:.2f} mm, base-wrench RMSE {r['base_wrench_rmse_N']:.2f} N")
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as fh:
            json.dump(res, fh, indent=2)

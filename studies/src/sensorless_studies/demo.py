"""`make demo`: the whole pipeline on a simulated Panda, needing nothing outside the repo.

1. a 'true' Panda = example-robot-data inertials perturbed (±20 % mass, ±2 cm CoM) + friction;
2. two different Fourier excitation trajectories, 200 Hz, torques by RNEA + noise (σ = 0.2 N·m);
3. identify OLS, WLS and LMI (physically consistent, γ by cross-validation) on the first;
   validate on the second against the CAD model;
4. write the logs, the model folder of the LMI model (result.json, model.urdf, joint_terms.json;
   :func:`~sensorless.identification.artifact.save_model_folder`, as ``identify`` does), torques.png,
   friction.png and report.html (:func:`~sensorless.report.write_html_report`); every method's held-out
   scores are in result.json ``validation`` (as ``identify --validate`` writes them) and ``demo``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Console

from sensorless.data import write_npz
from sensorless.torque_models import CADModel, PhysicalModel
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.identification.artifact import save_model_folder
from sensorless.parameters import check_physical_consistency
from sensorless.regressor import ModelStructure
from sensorless.report import metrics_table, plot_friction, plot_torques, write_html_report
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory

__all__ = ["run_demo"]

NOISE_STD = 0.2  # N·m


def run_demo(out: Path, seed: int = 0, console: Console | None = None) -> dict:
    console = console or Console()
    robot = load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"])
    truth = perturbed_truth(robot, rng=seed)
    rate, duration = 200.0, 20.0
    train = synthetic_trajectory(
        truth, random_fourier(robot, rng=seed + 1, base_freq=0.05).sample(rate, duration), noise_std=NOISE_STD, rng=seed + 2
    )
    test = synthetic_trajectory(
        truth, random_fourier(robot, rng=seed + 3, base_freq=0.05).sample(rate, duration), noise_std=NOISE_STD, rng=seed + 4
    )
    write_npz(train, out / "train.npz")
    write_npz(test, out / "validate.npz")

    structure = ModelStructure(robot)
    results = {"ols": identify(structure, train, method="ols", weights=None),  # ordinary least squares
               "wls": identify(structure, train, method="wls")}
    results["lmi"] = identify(structure, train, method="lmi", gamma="auto")
    cad = CADModel(robot).fit()
    # least squares as it is (the unconstrained solution, not the physical model identify presents from it)
    fits = {m: np.array(r.diagnostics["presented"].get("fit_parameters", r.parameters)) for m, r in results.items()}
    models = {m: PhysicalModel.from_parameters(r.structure, fits[m]) if m != "lmi" else r for m, r in results.items()}
    scores = {"CAD": cad.score(test), **{m.upper(): r.score(test) for m, r in models.items()}}
    console.print(metrics_table("Panda, held-out trajectory", scores, field="rmse"))
    console.print(metrics_table("Panda, held-out trajectory", scores, field="nrmse"))

    ols, lmi = results["ols"], results["lmi"]
    B = ols.base
    truth_base = B.base(truth.parameters(structure.joint_terms))
    rel_err = float(np.linalg.norm(B.base(fits["ols"]) - truth_base) / np.linalg.norm(truth_base))
    doc = lmi.to_dict()  # the model folder holds the LMI model: result.json and model.urdf are one model
    doc["demo"] = {
        "noise_std": NOISE_STD,
        "held_out": {k: v.to_dict() for k, v in scores.items()},
        "held_out_rmse_over_noise": {m: (scores[m].rmse / NOISE_STD).tolist() for m in ("OLS", "WLS", "LMI")},
        "ols_relative_base_parameter_error_norm": rel_err,
        "inconsistent_bodies": {
            m: [r.name for r in check_physical_consistency(fits[m][:structure.n_body_params], list(robot.body_names))
                if not r.consistent] for m in results},
        "settings": {"seed": seed, "rate_hz": rate, "duration_s": duration, "robot": "panda (fingers locked)"},
    }
    doc["validation"] = {"validate.npz": {"cad": scores["CAD"].to_dict(),
                                          **{m: scores[m.upper()].to_dict() for m in results}}}
    plot_torques(test.t, structure.target(test), {"OLS": models["ols"].predict(test), "LMI": lmi.predict(test), "CAD": cad.predict(test)},
                 structure.row_names, out / "torques.png", title="Panda: held-out torques", robot=structure.robot)
    plot_friction(structure, lmi.parameters, [train], out / "friction.png", title="Panda: joint friction (training log)")
    save_model_folder(out, lmi, doc)
    write_html_report(out, doc)
    console.print(
        f"held-out RMSE / noise σ: OLS {np.round(scores['OLS'].rmse / NOISE_STD, 3).tolist()}, "
        f"LMI {np.round(scores['LMI'].rmse / NOISE_STD, 3).tolist()} (1.0 = noise floor)"
    )
    console.print(
        "physically inconsistent bodies: "
        + ", ".join(f"{m.upper()} {len(b)}/{robot.n_bodies}" for m, b in doc["demo"]["inconsistent_bodies"].items())
        + f"; OLS base-parameter relative error (norm) {rel_err:.2e}; result.json and model.urdf: the LMI model "
        f"(γ = {lmi.diagnostics['gamma']:.3g})"
    )
    return doc

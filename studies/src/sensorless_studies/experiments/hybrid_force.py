"""The hybrid-force study: model-based vs learned vs hybrid force estimation in a trocar.

Simulated PSM-like arm (:mod:`sensorless_studies.simulation.trocar`), in the form of the Tables
II–IV of the "model + learned intraoperative correction" dVRK study:

(a) Table II — free space, train/test workspaces disjoint in yaw and pitch: per-joint
    torque RMSE of the identified model vs a pure-learning network, both fitted on
    workspace A and tested on workspace B.
(b) Table III — in the trocar (no tip contact), held-out log: per-joint torque NRMSE of
    the free-space model vs the hybrid (model + residual learned in the trocar).
(c) Table IV — in the trocar with tip contact: Cartesian tip-force RMSE and NRMSE per axis
    for model-based, hybrid and learning-only estimates against the simulated truth.

Plus payload identification on a free-space log with a known mass at the tool tip.
Accelerations and velocities come from the logged positions (Savitzky–Golay, ≈0.1 s); the
Coulomb smoothing of the model is chosen on held-out free-space data, not taken from the
simulator.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pinocchio as pin
from rich.console import Console
from rich.table import Table

from sensorless.data import savgol_derivatives
from sensorless.data.trajectory import Trajectory
from sensorless.estimation.force import CartesianForceEstimator
from sensorless.identification import identify, torque_metrics
from sensorless.identification.payload import identify_payload
from sensorless.io import versions, write_json_atomic
from sensorless.torque_models import PhysicalModel
from sensorless.learning import HybridModel, LearnedTorqueModel
from sensorless.regressor import ModelStructure
from ..simulation.surgical_arm import TIP_FRAME
from ..simulation.trocar import make_datasets, payload_log

__all__ = ["CONFIGS", "check_acceptance", "run", "select_coulomb_smoothing"]

JOINT_TERMS = ("fv", "fc", "offset", "armature")
AXES = ("x", "y", "z")
SMOOTHING_GRID = (0.0, 0.005, 0.01, 0.02, 0.05)  # rad/s (m/s)
_LEARN = dict(window=5, stride=2, hidden=(256, 256), activation="relu")
CONFIGS = {
    "quick": {
        "learning": {**_LEARN, "epochs": 150, "patience": 20, "batch_size": 256, "lr": 1e-3},
        "hybrid_per_joint": False,
        "payload": {"mass": 0.2, "com": [0.0, 0.0, 0.02], "inertia_diag": [2e-4, 2e-4, 1e-4], "duration": 30.0, "n_boot": 100},
    },
    "full": {
        "learning": {**_LEARN, "epochs": 300, "patience": 30, "batch_size": 256, "lr": 1e-3},
        "hybrid_per_joint": True,
        "payload": {"mass": 0.2, "com": [0.0, 0.0, 0.02], "inertia_diag": [2e-4, 2e-4, 1e-4], "duration": 60.0, "n_boot": 200},
    },
}


def select_coulomb_smoothing(robot, free: Trajectory, grid=SMOOTHING_GRID, train_fraction: float = 0.7) -> tuple[float, dict]:
    """Coulomb smoothing ε of sgn(q̇) ≈ tanh(q̇/ε), chosen like a user would: identify on the
    first part of the free-space log, keep the ε with the lowest mean NRMSE on the rest."""
    n = int(train_fraction * len(free))
    fit, val = free.take(slice(0, n)), free.take(slice(n, None))
    scores = {}
    for eps in grid:
        s = ModelStructure(robot, joint_terms=JOINT_TERMS, coulomb_smoothing=eps)
        scores[str(eps)] = float(np.mean(identify(s, fit).score(val).nrmse))
    best = min(grid, key=lambda e: scores[str(e)])
    return float(best), scores


def _stack(trajs: list[Trajectory], fn) -> np.ndarray:
    return np.vstack([fn(t) for t in trajs])


def _force_metrics(F: np.ndarray, truth: np.ndarray) -> dict:
    rmse = np.sqrt(((F - truth) ** 2).mean(axis=0))
    rng = truth.max(axis=0) - truth.min(axis=0)
    return {"rmse": dict(zip(AXES, rmse.tolist())), "nrmse": dict(zip(AXES, (rmse / rng).tolist())),
            "range": dict(zip(AXES, rng.tolist()))}


def check_acceptance(results: dict) -> dict:
    """The issue's simulation and payload acceptance criteria, evaluated on ``results``."""
    f = results["table_iv_force"]
    hyb = np.array([f["hybrid"]["nrmse"][a] for a in AXES])
    mod = np.array([f["model_based"]["nrmse"][a] for a in AXES])
    t2 = results["table_ii_workspace_mismatch"]
    ml, mm = t2["learning_only"]["mean_nrmse"], t2["model_based"]["mean_nrmse"]
    worse = [j for j in t2["joints"] if t2["learning_only"]["rmse"][j] > t2["model_based"]["rmse"][j]]
    p = results["payload"]
    return {
        "hybrid_force_nrmse_below_10pct_every_axis": bool(np.all(hyb < 0.10)),
        "hybrid_force_nrmse_reduction_vs_model": dict(zip(AXES, (1 - hyb / mod).tolist())),
        "hybrid_force_at_least_30pct_lower_every_axis": bool(np.all(hyb <= 0.7 * mod)),
        "learning_only_worse_than_model_under_mismatch_mean_nrmse": bool(ml > mm),
        "learning_only_worse_on_joints": worse,
        "payload_mass_error_below_5pct": bool(abs(p["mass_relative_error"]) < 0.05),
    }


def _table(title: str, header: list[str], rows: list[list[str]]) -> Table:
    t = Table(title=title)
    for i, h in enumerate(header):
        t.add_column(h, justify="left" if i == 0 else "right")
    for r in rows:
        t.add_row(*r)
    return t


def _markdown(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _tables(res: dict) -> dict[str, tuple[str, list[str], list[list[str]]]]:
    t2, t3, t4 = res["table_ii_workspace_mismatch"], res["table_iii_trocar_torque"], res["table_iv_force"]
    unit = {j: ("N" if j == "insertion" else "N·m") for j in t2["joints"]}
    rows2 = [[f"{j} [{unit[j]}]", f"{t2['model_based']['rmse'][j]:.4f}", f"{t2['learning_only']['rmse'][j]:.4f}"] for j in t2["joints"]]
    rows3 = [[j, f"{100 * t3['model_based']['nrmse'][j]:.2f}", f"{100 * t3['hybrid']['nrmse'][j]:.2f}"] for j in t3["joints"]]
    rows3.append(["mean", f"{100 * t3['model_based']['mean_nrmse']:.2f}", f"{100 * t3['hybrid']['mean_nrmse']:.2f}"])
    names = (("model_based", "model-based"), ("hybrid", "hybrid"), ("learning_only", "learning-only"))
    rows4 = [[a] + [f"{t4[k]['rmse'][a]:.3f} / {100 * t4[k]['nrmse'][a]:.1f}" for k, _ in names] for a in AXES]
    return {
        "II": ("Table II — free space, test workspace ≠ training workspace: torque RMSE",
               ["joint", "model-based", "learning-only"], rows2),
        "III": ("Table III — in the trocar (held-out, no contact): torque NRMSE [%]",
                ["joint", "model-based", "hybrid"], rows3),
        "IV": ("Table IV — tip contact in the trocar: force RMSE [N] / NRMSE [%]",
               ["axis"] + [n for _, n in names], rows4),
    }


def _figures(out: Path, con: Trajectory, forces: dict, trocar_test: Trajectory, preds: dict, joints: list[str], t2: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sensorless.report import plot_torques

    t = con.t - con.t[0]
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    truth = con.extras["f_tip"]
    for k, ax in enumerate(axes):
        ax.plot(t, truth[:, k], "k", lw=1.2, label="truth")
        for name, F in forces.items():
            ax.plot(t, F[:, k], lw=0.8, label=name)
        ax.set_ylabel(f"F{AXES[k]} [N]")
    axes[0].legend(ncol=4, fontsize=8, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Tip force with contact in the trocar")
    fig.tight_layout()
    fig.savefig(out / "forces.png", dpi=110)
    plt.close(fig)
    plot_torques(trocar_test.t, preds["measured"], {k: v for k, v in preds.items() if k != "measured"}, joints,
                 out / "trocar_torques.png", title="In the trocar, held-out: measured vs model-based vs hybrid",
                 units=["N" if j == "insertion" else "N·m" for j in joints])
    fig, ax = plt.subplots(figsize=(8, 3.5))
    x = np.arange(len(t2["joints"]))
    ax.bar(x - 0.2, [t2["model_based"]["nrmse"][j] * 100 for j in t2["joints"]], 0.4, label="model-based")
    ax.bar(x + 0.2, [t2["learning_only"]["nrmse"][j] * 100 for j in t2["joints"]], 0.4, label="learning-only")
    ax.set_xticks(x, t2["joints"], fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("NRMSE [%]")
    ax.set_title("Workspace mismatch (train A → test B)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "workspace_mismatch.png", dpi=110)
    plt.close(fig)


def run(out: Path, quick: bool = False, seed: int = 0, console: Console | None = None) -> dict:
    """Run the study; write ``results.json``, ``tables.md`` and figures into ``out``."""
    console = console or Console()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = CONFIGS["quick" if quick else "full"]
    learn = dict(cfg["learning"])
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    t0 = time.perf_counter()
    ds = make_datasets(seed, quick=quick)
    timings["simulate"] = time.perf_counter() - t0
    robot = ds.robot
    prep = savgol_derivatives  # default window ≈ 0.1 s
    free, split_a, split_b = prep(ds.free_space), prep(ds.split_train), prep(ds.split_test)
    tro_train = [prep(t) for t in ds.trocar_train]
    tro_test = [prep(t) for t in ds.trocar_test]
    contact = prep(ds.trocar_contact)
    t0 = time.perf_counter()
    eps, eps_scores = select_coulomb_smoothing(robot, free)
    timings["select_smoothing"] = time.perf_counter() - t0
    structure = ModelStructure(robot, joint_terms=JOINT_TERMS, coulomb_smoothing=eps)
    joints = list(structure.row_names)
    train_opts = {k: learn[k] for k in ("epochs", "patience", "batch_size", "lr")}
    net_opts = {k: learn[k] for k in ("window", "stride", "hidden", "activation")}

    # (a) workspace mismatch ---------------------------------------------------------
    t0 = time.perf_counter()
    model_a = PhysicalModel.from_parameters(structure, identify(structure, split_a).parameters)
    learn_a = LearnedTorqueModel(robot, seed=seed, **net_opts, **train_opts).fit(split_a)
    m_model, m_learn = model_a.score(split_b), learn_a.score(split_b)
    timings["a_workspace_mismatch"] = time.perf_counter() - t0
    t2 = {"joints": joints, "model_based": _metrics(m_model), "learning_only": _metrics(m_learn),
          "learning_history": _hist(learn_a.history_)}

    # (b) trocar torque ---------------------------------------------------------------
    t0 = time.perf_counter()
    ident = identify(structure, free)
    phys = PhysicalModel.from_parameters(structure, ident.parameters)
    hybrid = HybridModel(phys, per_joint=cfg["hybrid_per_joint"], seed=seed, **net_opts, **train_opts).fit(tro_train)
    meas = _stack(tro_test, structure.target)
    p_model, p_hybrid = _stack(tro_test, phys.predict), _stack(tro_test, hybrid.predict)
    timings["b_trocar_torque"] = time.perf_counter() - t0
    t3 = {"joints": joints, "model_based": _metrics(torque_metrics(meas, p_model, joints)),
          "hybrid": _metrics(torque_metrics(meas, p_hybrid, joints)), "hybrid_history": _hist(hybrid.history_),
          "free_space_identification": {"rank": ident.base.rank, "condition_number": ident.diagnostics["condition_number"],
                                        "train_nrmse": dict(zip(joints, ident.train_metrics.nrmse.tolist()))}}

    # (c) Cartesian force with tip contact ------------------------------------------
    t0 = time.perf_counter()
    learn_full = LearnedTorqueModel(robot, seed=seed, **net_opts, **train_opts).fit([free, *tro_train])
    est = CartesianForceEstimator(robot, TIP_FRAME, "local_world_aligned", components="linear")
    f_true = contact.extras["f_tip"]
    forces = {"model-based": est.estimate(contact, phys).F, "hybrid": est.estimate(contact, hybrid).F,
              "learning-only": est.estimate(contact, learn_full).F}
    timings["c_force"] = time.perf_counter() - t0
    in_contact = contact.extras["in_contact"] > 0
    t4 = {key: _force_metrics(forces[name], f_true) for key, name in
          (("model_based", "model-based"), ("hybrid", "hybrid"), ("learning_only", "learning-only"))}
    t4["in_contact_only"] = {key: _force_metrics(forces[name][in_contact], f_true[in_contact]) for key, name in
                             (("model_based", "model-based"), ("hybrid", "hybrid"), ("learning_only", "learning-only"))}
    t4["contact_fraction"] = float(in_contact.mean())
    t4["estimator"] = est.settings()
    t4["learning_only_history"] = _hist(learn_full.history_)

    # payload ---------------------------------------------------------------------------
    t0 = time.perf_counter()
    pc = cfg["payload"]
    inertia = pin.Inertia(pc["mass"], np.array(pc["com"]), np.diag(pc["inertia_diag"]))
    plog = prep(payload_log(ds, inertia, frame=TIP_FRAME, duration=pc["duration"], seed=seed))
    pay = identify_payload(ident, plog, TIP_FRAME, mode="auto", n_boot=pc["n_boot"], seed=seed)
    timings["payload"] = time.perf_counter() - t0
    payload = {**pay.to_dict(), "true_mass": pc["mass"], "true_com": pc["com"],
               "mass_relative_error": (pay.mass - pc["mass"]) / pc["mass"],
               "com_error_mm": ((pay.com - np.array(pc["com"])) * 1e3).tolist()}

    timings["total"] = time.perf_counter() - t_all
    results = {
        "study": "hybrid-force", "quick": quick, "seed": seed,
        "table_ii_workspace_mismatch": t2, "table_iii_trocar_torque": t3, "table_iv_force": t4, "payload": payload,
        "settings": {"config": cfg, "joint_terms": list(JOINT_TERMS), "coulomb_smoothing": eps,
                     "coulomb_smoothing_validation": eps_scores, "coulomb_smoothing_truth": ds.truth.coulomb_eps,
                     "derivatives": "savgol_derivatives(default window ≈ 0.1 s, polyorder 3, centred)",
                     "hybrid_training_logs": [t.source for t in tro_train],
                     "learning_only_training_logs": [free.source] + [t.source for t in tro_train],
                     "simulation": ds.settings},
        "timings_s": timings, "versions": versions(),
    }
    results["acceptance"] = check_acceptance(results)
    tables = _tables(results)
    md = []
    for title, header, rows in tables.values():
        console.print(_table(title, header, rows))
        md += [f"### {title}", "", _markdown(header, rows), ""]
    md += [f"Payload: {pay} — true {pc['mass']:.3f} kg, error {100 * payload['mass_relative_error']:+.2f} %", ""]
    console.print(md[-2])
    (out / "tables.md").write_text("\n".join(md))
    tt = tro_test[-1]
    _figures(out, contact, forces, tt,
             {"measured": structure.target(tt), "model-based": phys.predict(tt), "hybrid": hybrid.predict(tt)}, joints, t2)
    write_json_atomic(results, out / "results.json")
    acc = results["acceptance"]
    console.print(f"acceptance: {', '.join(f'{k}={v}' for k, v in acc.items() if isinstance(v, bool))}")
    return results


def _metrics(m) -> dict:
    return {"rmse": dict(zip(m.joints, m.rmse.tolist())), "nrmse": dict(zip(m.joints, m.nrmse.tolist())),
            "mean_rmse": float(np.mean(m.rmse)), "mean_nrmse": float(np.mean(m.nrmse)), "n_samples": m.n_samples}


def _hist(h: dict) -> dict:
    return {k: h.get(k) for k in ("epochs_run", "best_epoch", "best_val_loss", "stopped_early", "seconds", "n_train", "n_val")}

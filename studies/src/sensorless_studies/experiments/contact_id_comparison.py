"""What the contact study compares and how it reports it, for both of its formulations
(:mod:`.contact_id`, with accelerations; :mod:`.contact_id_filtered`, without): the torque models
(LMI, SVD, MLP; ``cfg`` is the study's :class:`~.contact_id.ContactStudyConfig`), the projected
RMSE they are scored by, their parameter errors, the acceptance checks, the table and the figure."""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np

from sensorless.data.imu import gravity_in_base
from sensorless.data.trajectory import Trajectory
from sensorless.errors import IdentifiabilityWarning
from sensorless.parameters import com_frame
from sensorless.regressor.contact import ContactStructure
from sensorless.torque_models import PhysicalModel

__all__ = ["TABLE_HEAD", "acceptance_checks", "estimators", "fit_all", "jsonable", "mlp_epochs", "model_lines", "parameter_errors",
           "projected_rmse", "save", "sensor_features", "table", "table_line", "with_parameters"]


def sensor_features(traj: Trajectory) -> np.ndarray:
    """What the black-box model sees: q, v, base twist, gravity in the base frame, contact flags."""
    gz = -gravity_in_base(traj.base_q, 1.0)  # world z axis in the base frame
    contact = np.asarray(traj.extras["contact"], dtype=float)
    return np.hstack([traj.q, traj.v, traj.base_v, gz, contact])


def projected_rmse(structure: ContactStructure, traj: Trajectory, predicted: np.ndarray, target: np.ndarray) -> float:
    """sqrt(mean ‖r_n‖² / n_actuated) of a projected residual (N, nv)."""
    r = predicted - target
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)) / structure.robot.n_actuated))


def mlp_epochs(cfg, n: int) -> int:
    """The MLP's epochs for ``n`` training samples under the config's CPU budget:
    clip(budget / n, 3, ``cfg.mlp_epochs``) (``cfg.mlp_epochs`` when there is no budget)."""
    if cfg.mlp_sample_budget <= 0:
        return cfg.mlp_epochs
    return int(np.clip(cfg.mlp_sample_budget // max(n, 1), 3, cfg.mlp_epochs))


def parameter_errors(structure: ContactStructure, params: np.ndarray, true_params: np.ndarray) -> dict:
    """Total and per-link mass, CoM and joint-term errors of ``params`` against the simulation's ``true_params``."""
    nb = structure.robot.n_bodies
    est = params[: 10 * nb].reshape(nb, 10)
    tru = true_params[: 10 * nb].reshape(nb, 10)
    m_e, c_e, _ = com_frame(est)
    m_t, c_t, _ = com_frame(tru)
    out = {
        "total_mass_true": float(m_t.sum()),
        "total_mass_estimated": float(m_e.sum()),
        "total_mass_relative_error": float(abs(m_e.sum() - m_t.sum()) / m_t.sum()),
        "link_mass_abs_error_mean": float(np.mean(np.abs(m_e - m_t))),
        "link_mass_relative_error_median": float(np.median(np.abs(m_e - m_t) / np.maximum(m_t, 1e-9))),
        "link_com_error_mean_m": float(np.mean(np.linalg.norm(c_e - c_t, axis=1))),
    }
    for term in ("fv", "fc", "armature"):
        if term in structure.joint_terms:
            idx = [structure.joint_term_index(j, term) for j in structure.robot.actuated_joints]
            out[f"{term}_abs_error_mean"] = float(np.mean(np.abs(params[idx] - true_params[idx])))
            out[f"{term}_true_mean"] = float(np.mean(np.abs(true_params[idx])))
    return out


def estimators(cfg, structure: ContactStructure, n: int) -> dict:
    """The compared torque models, unfitted (one loop fits and scores them all):

    * LMI: physically consistent, pullback prior weight ``cfg.gamma``, unweighted rows;
    * SVD: unconstrained minimum-norm truncated SVD (identify's default two-step weights);
    * MLP: black box on :func:`sensor_features`, its torques projected for scoring.
    """
    from sensorless.learning.models import MLPTorqueModel

    return {
        "LMI": PhysicalModel(structure=structure, method="lmi", gamma=cfg.gamma, regularization="pullback",
                             weights=None),
        "SVD": PhysicalModel(structure=structure, method="svd"),
        "MLP": MLPTorqueModel(hidden=cfg.mlp_hidden, activation=cfg.mlp_activation, features=sensor_features,
                              epochs=mlp_epochs(cfg, n), seed=cfg.seed, num_threads=2,
                              batch_size=min(256, max(32, n // 8))),
    }


def fit_all(models: dict, ne, train: Trajectory, t_equations: float, seconds: dict) -> dict:
    """Fit every model (the physical ones on the shared equations ``ne``, built in
    ``t_equations`` s, the others on ``train``); wall times into ``seconds``."""
    for name, model in models.items():
        physical = isinstance(model, PhysicalModel)
        t = time.perf_counter()
        with warnings.catch_warnings():
            if name == "LMI":  # as the direct solver call it replaces: identifiability is SVD's report
                warnings.simplefilter("ignore", IdentifiabilityWarning)
            model.fit(ne if physical else train)
        if name == "SVD":  # the paper's baseline is the unconstrained solution itself, not the model identify presents
            fit = model.result_.diagnostics.get("presented", {}).get("fit_parameters")
            if fit is not None:
                model.parameters_ = np.asarray(fit, dtype=float)
        seconds[name.lower()] = (t_equations if physical else 0.0) + time.perf_counter() - t
    return models


def with_parameters(row: dict, structure: ContactStructure, models: dict, true_params: np.ndarray) -> dict:
    """``row`` with the LMI and SVD fits' parameter errors and the LMI solver's status."""
    lmi = models["LMI"]
    row["parameters"] = {k: parameter_errors(structure, models[k].parameters_, true_params) for k in ("LMI", "SVD")}
    row["lmi_status"] = lmi.result_.diagnostics["lmi"]["status"]
    row["lmi_consistent"] = lmi.result_.diagnostics["lmi"]["consistent"]
    return row


def save(results: dict, out: Path, table: str) -> dict:
    """Write ``results.json``, ``table.md`` and the sample-efficiency figure into ``out``; return ``results``."""
    (out / "results.json").write_text(json.dumps(results, indent=2))
    (out / "table.md").write_text(table)
    _figure(results, out / "sample_efficiency.png")
    return results


def acceptance_checks(rows: list[dict], floors: dict, true_rmse: dict) -> dict:
    """The acceptance properties, evaluated on this run."""
    if not rows:
        return {}
    big, small = rows[-1], rows[0]
    groups = ("validation", "ood_trot", "ood_jump")
    return {
        "lmi_beats_svd_everywhere": all(r["rmse"]["LMI"][g] < r["rmse"]["SVD"][g] for r in rows for g in groups),
        "lmi_beats_mlp_smallest_set": all(small["rmse"]["LMI"][g] < small["rmse"]["MLP"][g] for g in groups),
        "lmi_beats_mlp_ood_every_size": all(r["rmse"]["LMI"][g] < r["rmse"]["MLP"][g] for r in rows for g in ("ood_trot", "ood_jump")),
        "jump_lmi_over_mlp_largest": big["rmse"]["LMI"]["ood_jump"] / big["rmse"]["MLP"]["ood_jump"],
        "jump_lmi_over_svd_largest": big["rmse"]["LMI"]["ood_jump"] / big["rmse"]["SVD"]["ood_jump"],
        "jump_lmi_over_svd_worst": max(r["rmse"]["LMI"]["ood_jump"] / r["rmse"]["SVD"]["ood_jump"] for r in rows),
        "jump_lmi_over_mlp_worst": max(r["rmse"]["LMI"]["ood_jump"] / r["rmse"]["MLP"]["ood_jump"] for r in rows),
        "validation_lmi_over_noise_floor_largest": big["rmse"]["LMI"]["validation"] / floors["validation"],
        "validation_lmi_over_true_parameters_largest": big["rmse"]["LMI"]["validation"] / true_rmse["validation"],
        "total_mass_error_largest": big["parameters"]["LMI"]["total_mass_relative_error"],
        "mlp_wins_in_distribution_largest": big["rmse"]["MLP"]["validation"] < big["rmse"]["LMI"]["validation"],
    }


TABLE_HEAD = ("| train samples | model | validation | OOD trot | OOD jump |", "|---|---|---|---|---|")


def table_line(n_train, label: str, rmse: dict) -> str:
    """``| n_train | label | validation | OOD trot | OOD jump |`` with RMSEs to 4 decimals."""
    return f"| {n_train} | {label} | {' | '.join(f'{rmse[g]:.4f}' for g in ('validation', 'ood_trot', 'ood_jump'))} |"


def model_lines(rows: list[dict], key: str = "rmse") -> list[str]:
    """One table line per training size and model, from ``row[key][model]``."""
    return [table_line(r["n_train"], m, r[key][m]) for r in rows for m in ("LMI", "SVD", "MLP")]


def table(res: dict) -> str:
    """Markdown table in the form of the paper's Table I (projected-torque RMSE, N·m)."""
    lines = [*TABLE_HEAD, *model_lines(res["rows"]),
             table_line("—", "noise floor", res["noise_floor_rmse"]),
             table_line("—", "true parameters", res["true_parameters_rmse"])]
    return "\n".join(lines) + "\n"


def _figure(res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = (("validation", "validation (5 logs)"), ("ood_trot", "OOD trot"), ("ood_jump", "OOD jump"))
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=True)
    n = [r["n_train"] for r in res["rows"]]
    for ax, (g, title) in zip(axes, groups):
        for m, style in (("LMI", "o-"), ("SVD", "s--"), ("MLP", "^-.")):
            ax.loglog(n, [r["rmse"][m][g] for r in res["rows"]], style, label=m)
        ax.axhline(res["noise_floor_rmse"][g], color="k", lw=0.8, ls=":", label="noise floor")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("training samples")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("projected torque RMSE [N·m]")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def jsonable(x):
    """``x`` with its tuples as lists (nested), for JSON."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    return x

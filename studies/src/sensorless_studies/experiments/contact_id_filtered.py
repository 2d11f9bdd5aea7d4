"""The legged-robot study without accelerations (``--acceleration none``): the identification
and the evaluation on the filtered momentum regressor L[P Sᵀτ] = W_f θ
(:mod:`sensorless.regressor.integral`). Called by :func:`.contact_id.run`."""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from sensorless.data.trajectory import Trajectory
from .contact_id_comparison import (
    TABLE_HEAD,
    acceptance_checks,
    estimators,
    fit_all,
    jsonable,
    mlp_epochs,
    model_lines,
    projected_rmse,
    save,
    table,
    table_line,
    with_parameters,
)

__all__ = ["run_acceleration_free"]


def run_acceleration_free(cfg, sets, structure, true_params, nominal, out: Path, console, t_start) -> dict:
    """The study on the filtered momentum regressor: L[P Sᵀτ] = W_f θ (no v̇ anywhere).

    Training: for every size, random samples of the pool; each log is filtered whole and
    its drawn rows are folded into that size's normal equations (one pass, one log in
    memory). The MLP is trained on the raw samples of the same indices.

    Scores (``rmse``), per evaluation group, in the filtered space: RMSE of L[P Sᵀ(τ̂ − τ)],
    for the LMI/SVD W_f θ − y_f, for the MLP the filtered projection of its predicted torques
    (:func:`~sensorless.regressor.integral.filtered_target`). Two floors, both in this space:
    ``noise_floor_rmse`` (torque noise only: logged against noiseless torque, as in the other
    modes) and ``noise_floor_all_signals_rmse`` (the true parameters' residual on the noisy
    log minus their residual on the noiseless log: what the measurement noise of q, v, base
    state and τ puts into the filtered equation). ``formulation_rmse``: the true parameters
    on the noiseless log (the discretisation error). ``rmse_exact_acceleration``: the
    unfiltered projected residual with the simulator's accelerations on the evaluation logs,
    the metric of ``--acceleration simulator`` (identified model scored, not the log).
    """
    from sensorless.regressor.normal_equations import NormalEquations
    from sensorless.regressor.integral import filtered_rows, filtered_target

    fk = {"order": cfg.filter_order, "tau_hold": "mean" if cfg.tau_log == "mean" else "linear"}
    fc = cfg.filter_cutoff
    true_robot = sets.pool_truth[0].robot
    cols = [true_robot.joint_names.index(j) for j in nominal.actuated_joints]
    th = true_params
    evals, floors_all, formulation, exact = {}, {}, {}, {}
    for group, items in sets.evals.items():
        evals[group], fa, fo = [], [], []
        for traj, gt in items:
            fr = filtered_rows(structure, traj, fc, **fk)
            fr0 = filtered_rows(structure, gt.trajectory().with_(joint_names=traj.joint_names), fc, **fk)
            clean = filtered_target(structure, traj, gt.tau[:, cols], fc, **fk)
            r, r0 = fr.W @ th - fr.y, fr0.W @ th - fr0.y
            fa.append(projected_rmse(structure, traj, r, r0))
            fo.append(projected_rmse(structure, traj, r0, 0 * r0))
            evals[group].append((traj, fr, projected_rmse(structure, traj, clean, fr.y)))
            tx = traj.with_(a=gt.a, base_a=gt.base_a)
            yx = structure.target(tx)
            exact.setdefault(group, []).append(
                (tx, yx, projected_rmse(structure, tx, structure.project(tx, gt.tau[:, cols]), yx)))
        floors_all[group], formulation[group] = float(np.mean(fa)), float(np.mean(fo))
    floors = {g: float(np.mean([f for _, _, f in v])) for g, v in evals.items()}
    floors_exact = {g: float(np.mean([f for _, _, f in v])) for g, v in exact.items()}
    true_rmse = {g: float(np.mean([projected_rmse(structure, t, fr.W @ th, fr.y) for t, fr, _ in v]))
                 for g, v in evals.items()}

    rng = np.random.default_rng(cfg.seed)
    lengths = [len(t) for t in sets.pool]
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    sizes = [n for n in cfg.train_sizes if n <= offsets[-1]]
    draws = {n: np.sort(rng.choice(offsets[-1], size=n, replace=False)) for n in sizes}
    nes = {n: NormalEquations.zeros(structure.n_rows, structure.n_params) for n in sizes}
    t = time.perf_counter()
    for k, traj in enumerate(sets.pool):
        fr = filtered_rows(structure, traj, fc, **fk)
        for n in sizes:
            local = draws[n][(draws[n] >= offsets[k]) & (draws[n] < offsets[k + 1])] - offsets[k]
            if local.size:
                nes[n].add(fr.W[local], fr.y[local])
    t_rows = (time.perf_counter() - t) / len(sizes)
    whole = Trajectory.concatenate(sets.pool)
    rows = []
    for n in sizes:
        idx = draws[n]
        row: dict[str, Any] = {"n_train": n, "rmse": {}, "rmse_exact_acceleration": {}, "seconds": {}}
        models = fit_all(estimators(cfg, structure, n), nes[n], whole.take(idx), t_rows, row["seconds"])
        lmi, svd, mlp = models["LMI"], models["SVD"], models["MLP"]
        row["mlp_epochs"] = mlp_epochs(cfg, n)
        mlp_tau = {g: [mlp.predict(tr) for tr, _, _ in v] for g, v in evals.items()}
        filt = {
            "LMI": lambda g, i, tr, fr: fr.W @ lmi.parameters_,
            "SVD": lambda g, i, tr, fr: fr.W @ svd.parameters_,
            "MLP": lambda g, i, tr, fr: filtered_target(structure, tr, mlp_tau[g][i], fc, **fk),
        }
        unf = {
            "LMI": lambda g, i, tr: structure.torques(lmi.parameters_, tr),
            "SVD": lambda g, i, tr: structure.torques(svd.parameters_, tr),
            "MLP": lambda g, i, tr: structure.project(tr, mlp_tau[g][i]),
        }
        for name in filt:
            row["rmse"][name] = {g: float(np.mean([projected_rmse(structure, tr, filt[name](g, i, tr, fr), fr.y)
                                                   for i, (tr, fr, _) in enumerate(v)])) for g, v in evals.items()}
            row["rmse_exact_acceleration"][name] = {
                g: float(np.mean([projected_rmse(structure, tr, unf[name](g, i, tr), y) for i, (tr, y, _) in enumerate(v)]))
                for g, v in exact.items()}
        rows.append(with_parameters(row, structure, models, true_params))
        if console is not None:
            r, x = row["rmse"], row["rmse_exact_acceleration"]
            console.print(
                f"n={n:>6d}  validation LMI {r['LMI']['validation']:.4f} SVD {r['SVD']['validation']:.4f} "
                f"MLP {r['MLP']['validation']:.4f} (floor τ {floors['validation']:.4f}, all {floors_all['validation']:.4f}) | "
                f"jump LMI {r['LMI']['ood_jump']:.4f} MLP {r['MLP']['ood_jump']:.4f} "
                f"(exact-acc LMI {x['LMI']['ood_jump']:.4f} MLP {x['MLP']['ood_jump']:.4f}) | "
                f"mass err {100 * row['parameters']['LMI']['total_mass_relative_error']:.2f} %"
            )
    checks = acceptance_checks(rows, floors, true_rmse)
    if rows:
        big = rows[-1]
        checks["validation_lmi_over_all_signals_floor_largest"] = big["rmse"]["LMI"]["validation"] / floors_all["validation"]
        checks["true_parameters_over_noise_floor"] = true_rmse["validation"] / floors["validation"]
        xs = big["rmse_exact_acceleration"]
        checks["jump_lmi_over_mlp_exact_acceleration_largest"] = xs["LMI"]["ood_jump"] / xs["MLP"]["ood_jump"]
        checks["trot_lmi_over_mlp_largest"] = big["rmse"]["LMI"]["ood_trot"] / big["rmse"]["MLP"]["ood_trot"]
    results = {
        "study": "contact-id", "formulation": "acceleration-free filtered momentum regressor",
        "config": jsonable(asdict(cfg)), "robot": cfg.robot, "noise": asdict(sets.pool_truth[0].noise),
        "noise_floor_rmse": floors, "noise_floor_all_signals_rmse": floors_all, "formulation_rmse": formulation,
        "true_parameters_rmse": true_rmse, "noise_floor_exact_acceleration_rmse": floors_exact, "rows": rows,
        "checks": checks, "wall_seconds": time.perf_counter() - t_start,
    }
    return save(results, out, table(results) + _table_exact(results))


def _table_exact(res: dict) -> str:
    """The acceleration-free run's extra rows: floors in the filtered space, and the models
    scored unfiltered with the simulator's accelerations (comparable to --acceleration simulator)."""
    lines = [table_line("—", "noise floor, all signals", res["noise_floor_all_signals_rmse"]),
             table_line("—", "formulation (true parameters, noiseless)", res["formulation_rmse"]),
             "", "Unfiltered projected RMSE with the simulator's accelerations on the evaluation logs:", "",
             *TABLE_HEAD, *model_lines(res["rows"], "rmse_exact_acceleration"),
             table_line("—", "noise floor", res["noise_floor_exact_acceleration_rmse"])]
    return "\n".join(lines) + "\n"

"""What `sensorless identify` writes and prints besides result.json: figures, bodies, γ, wrench checks,
the plausibility check before anything is written."""

from __future__ import annotations

import math
from pathlib import Path

from .common import (
    err_console,
    warn_line,
)
from .console import console


PLOT_WINDOW = 20_000  # samples of the log shown in torques.png (from its start)
PLOT_POINTS = 2_000  # points per curve after decimation


def _plot_window(traj, structure, models: dict, out_dir: Path, title: str) -> list[Path]:
    """torques.png (or torques_<limb>.png per limb of a robot with several): measured vs predicted effort
    and the residuals on the first ``PLOT_WINDOW`` samples, every k-th sample (≤ ``PLOT_POINTS`` points).
    Only those samples are predicted (the model is pointwise in q, v, v̇)."""
    import numpy as np

    from .. import report

    n = min(len(traj), PLOT_WINDOW)
    part = traj.take(np.arange(0, n, max(1, math.ceil(n / PLOT_POINTS))))
    span = f"first {part.t[-1] - traj.t[0]:.3g} s" if n < len(traj) else "whole log"
    figs = report.plot_torques_by_limb(part.t, structure.target(part), {k: m.predict(part) for k, m in models.items()},
                                       structure.row_names, out_dir, robot=structure.robot,
                                       title=f"{title} ({span}, {len(part)} points)")
    return list(figs)


def _figure_jobs(shown, structure, models: dict, train, params, out_dir: Path, torque_title: str | None,
                 friction_title: str | None) -> list:
    """The figures of :func:`_plot_window` (``torque_title`` given) and friction.png (``friction_title``
    given) as jobs for :class:`~sensorless.cli.figure_process.FigureProcess`: every array the drawing
    needs is computed here (predictions, units, limbs, friction dots and curves), none of it by the child."""
    import numpy as np

    from ..report.rows import effort_unit, grouped_paths, limb_groups

    jobs: list = []
    if torque_title is not None:
        n = min(len(shown), PLOT_WINDOW)
        part = shown.take(np.arange(0, n, max(1, math.ceil(n / PLOT_POINTS))))
        span = f"first {part.t[-1] - shown.t[0]:.3g} s" if n < len(shown) else "whole log"
        title = f"{torque_title} ({span}, {len(part)} points)"
        measured = np.asarray(structure.target(part))
        preds = {k: np.asarray(m.predict(part)) for k, m in models.items()}
        rows, robot = list(structure.row_names), structure.robot
        groups = limb_groups(robot, rows)
        paths = grouped_paths(out_dir, "torques", groups)
        for g, members in groups.items():
            cols = [rows.index(m) for m in members]
            jobs.append(("torques", dict(t=part.t, measured=measured[:, cols],
                                         predictions={k: v[:, cols] for k, v in preds.items()}, rows=members,
                                         units=[effort_unit(robot, m) for m in members],
                                         title=f"{title}: {g}" if g and title else title or g), paths[g]))
    if friction_title is not None:
        from ..report.friction_plot import friction_panels

        jobs.append(("friction", {**friction_panels(structure, params, train), "title": friction_title},
                     out_dir / "friction.png"))
    return jobs


def _print_bodies(result) -> None:
    """Mass per body, named by joint and link (result.json: parameter_links), with its verdict
    (diagnostics.verdicts): a mass the data do not determine is shown as '—', never as identified."""
    from rich.table import Table

    from ..identification.result import body_links

    links = body_links(result.robot)
    verdicts = (result.diagnostics.get("verdicts") or {}).get("bodies", {})
    t = Table(title="identified bodies (parameters 'joint.p' in result.json; 'link.p' in parameter_links; "
                    "verdicts in diagnostics.verdicts)")
    for col in ("joint", "link", "m [kg]", "± (data) [kg]", "CAD m [kg]", "mass from", "CoM / inertia from"):
        t.add_column(col, justify="left" if col in ("joint", "link", "mass from", "CoM / inertia from") else "right")
    pi, pi0 = result.inertial_parameters.reshape(-1, 10), result.robot.inertial_parameters().reshape(-1, 10)
    for k, b in enumerate(result.robot.body_names):
        v = verdicts.get(b)
        if v is None:  # no verdicts (an older result): the value, unlabelled
            t.add_row(b, links.get(b, b), f"{pi[k, 0]:.3f}", "", f"{pi0[k, 0]:.3f}", "", "")
            continue
        mv = v["mass"]["verdict"]
        std = v["mass"]["std_data"]
        rest = [v[q]["verdict"] for q in v if q != "mass"]
        t.add_row(b, links.get(b, b), f"{pi[k, 0]:.3f}" if mv == "data" else "—",
                  f"{std:.2g}" if mv == "data" and std is not None else "", f"{pi0[k, 0]:.3f}", mv,
                  ", ".join(f"{n} {rest.count(n)}" for n in ("data", "prior", "undetermined") if rest.count(n)))
    tot = (result.diagnostics.get("verdicts") or {}).get("robot", {}).get("total_mass")
    if tot is not None and tot["verdict"] == "data":  # e.g. a floating base, or a passive rail carrying it all
        std = tot["std_data"]
        t.add_row("total", "", f"{tot['value']:.3f}", f"{std:.2g}" if std is not None else "", f"{tot['prior']:.3f}",
                  "data", "")
    console.print(t)


def _floating_base_checks(structure, result, doc: dict, train, val, validate) -> None:
    """Measured-wrench identification: bias values, world-axis base-wrench RMSE and the
    CoM-vs-CoP check on standing windows, per log, into ``doc["floating_base"]``."""
    if not getattr(structure, "measured_wrench", False):
        return
    from ..identification.floating_base import base_wrench_metrics, com_cop_check

    p = result.parameters
    fb = {"contact_rows": structure.settings()["contact_rows"], "wrench_offset": structure.offset_values(p),
          "train": [], "validation": {}}
    from ..regressor.contact_inference import contact_summary

    for traj in train:
        fb["train"].append({"base_wrench": base_wrench_metrics(structure, p, traj),
                            "com_cop": com_cop_check(structure, p, traj),
                            "contacts": contact_summary(structure, traj)})
    for path, traj in zip(validate, val):
        fb["validation"][str(path)] = {"base_wrench": base_wrench_metrics(structure, p, traj),
                                       "com_cop": com_cop_check(structure, p, traj)}
    doc["floating_base"] = fb
    mass = doc.get("mass_properties") or {}
    bw = fb["train"][0]["base_wrench"]
    cc = fb["train"][0]["com_cop"]
    console.print(
        f"identified total mass {mass.get('total_mass', float('nan')):.3f} kg (model file "
        f"{mass.get('urdf_total_mass', float('nan')):.3f} kg); base-wrench RMSE (world) {bw['force_rmse_norm']:.3g} N, "
        f"{bw['moment_rmse_norm']:.3g} N·m"
        + (f"; CoM–CoP on standing windows {1e3 * cc['distance_mean']:.1f} mm" if cc["n_samples"] else ""))
    for traj_doc in fb["train"]:
        c = traj_doc["contacts"]
        console.print(f"contact flags from the {c['source']}: in contact "
                      + ", ".join(f"{k} {100 * v:.0f} %" for k, v in c["fraction"].items()) + " of the samples",
                      highlight=False)
        missed = {k: v for k, v in c.get("loaded_unflagged", {}).items() if v}
        if missed:
            err_console.print(f"[yellow]warning:[/] the log's contact flags leave out samples whose measured normal "
                              f"force is above the noise: {missed} (those forces are not used)")
    for traj_doc in fb["train"]:
        if traj_doc["com_cop"]["ok"] is False:
            err_console.print(f"[yellow]warning:[/] the identified CoM is {1e3 * traj_doc['com_cop']['distance_mean']:.1f} mm "
                              "from the measured CoP on standing windows (a wrench bias? try --wrench-offset)")


def _gamma_note(d: dict) -> str:
    """γ used, with the cross-validation winner and floor when the runaway guard raised it, and active bounds."""
    g = d.get("gamma_guard") or {}
    note = f"γ = {d['gamma']:.3g}"
    if g.get("applied"):
        note += f" (cross-validation chose {g['gamma_cv']:.3g}; raised to the floor {g['floor']:.3g})"
    bounds = ((d.get("verdicts") or {}).get("active_bounds") or {}).get("bodies") or {}
    if bounds:
        note += "; active bounds: " + ", ".join(f"{b} ({'/'.join(v)})" for b, v in list(bounds.items())[:4])
        note += " ..." if len(bounds) > 4 else ""
    return note


def _plausible(result, lmi_kw: dict, accept: bool, urdf_values: str = "prior") -> None:
    """Plausibility of the fitted model before anything is written (PlausibilityError → exit 2, no
    output folder); with --accept-implausible the problems are printed and kept in result.json."""
    from ..identification.plausibility import check_plausibility

    problems = check_plausibility(result, lmi_kw.get("prior"), lmi_kw.get("ellipsoids"), accept=accept,
                                  urdf_values=urdf_values)
    if problems:
        result.diagnostics["implausible_accepted"] = problems
        for p in problems:
            warn_line(f"implausible (kept: --accept-implausible): {p}")

"""The figures of a run, as jobs (``(kind, arrays, path)``) a separate process can draw: torques.png
(measured against each model, with residuals, on a decimated window; one per limb) and friction.png.
Every array the drawing needs is computed here."""

from __future__ import annotations

import math
from pathlib import Path

__all__ = ["PLOT_WINDOW", "PLOT_POINTS", "plot_window", "figure_jobs", "figure_layouts"]

PLOT_WINDOW = 20_000  # samples of the log shown in torques.png (from its start)
PLOT_POINTS = 2_000  # points per curve after decimation


def plot_window(traj, structure, models: dict, out_dir: Path, title: str) -> list[Path]:
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


def figure_jobs(shown, structure, models: dict, train, params, out_dir: Path, torque_title: str | None,
                 friction_title: str | None) -> list:
    """The figures of :func:`plot_window` (``torque_title`` given) and friction.png (``friction_title``
    given) as jobs for a figure process (``sensorless.report.plot_process.draw_job`` draws one): every array the drawing
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


def figure_layouts(structure, torques: bool, friction: bool, out_dir: Path) -> list:
    """What the figures of :func:`figure_jobs` (with titles) will look like before their data exist:
    ``(kind, (rows or joints, has a title), path)`` per figure, torques.png per limb and friction.png.
    A figure process builds these empty figures while the model is fitted; a job whose figure
    differs (the model's rows changed) is drawn afresh."""
    from ..report.rows import grouped_paths, limb_groups

    out: list = []
    if torques:
        groups = limb_groups(structure.robot, list(structure.row_names))
        paths = grouped_paths(out_dir, "torques", groups)
        out += [("torques", (len(members), True), paths[g]) for g, members in groups.items()]
    if friction:
        out.append(("friction", (len(structure.robot.term_joints), True), Path(out_dir) / "friction.png"))
    return out

"""``excite``'s figure: the exported trajectory (position, velocity, acceleration per joint) against
its limits.

Per joint a row of three panels over the exported samples: q, v, v̇ with the excitation limits
(dashed orange: the box the optimiser kept, ``--position-fraction``, ``--max-velocity``,
``--max-acceleration``) and the robot model's own limits where it has them (solid red). Each row's
title gives the share of each excitation limit the trajectory uses. A robot with several limbs is
drawn one limb per figure (``excitation_<limb>.png``, :mod:`.rows`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .figure_kit import figure_legend, new_figure, save_figure, stride_indices
from .rows import grouped_paths, limb_groups, motion_units

__all__ = ["excitation_figure", "plot_excitation"]


def excitation_figure(traj, limits, hard: dict | None = None, *, robot=None, rows: Sequence[str] | None = None,
                      title: str = "", max_points: int = 3000):
    """The figure (module docstring) of ``traj`` (a :class:`~sensorless.data.Trajectory` with q, v, a)
    against ``limits`` (:class:`~sensorless.excitation.ExcitationLimits`) and ``hard`` (the robot's own,
    :func:`~sensorless.excitation.robot_limits`: lower, upper, velocity; ±inf where none)."""
    from matplotlib.lines import Line2D

    names = list(traj.joint_names)
    rows = names if rows is None else list(rows)
    idx = stride_indices(len(traj), max_points)
    t = np.asarray(traj.t, float)[idx] - float(traj.t[0])
    n = len(rows)
    top = 0.7 + (0.3 if title else 0.0)
    fig = new_figure(13.0, top + 0.6 + 1.25 * n + 0.35 * (n - 1))
    w, h = fig.get_figwidth(), fig.get_figheight()
    cell = (h - top - 0.6 - 0.35 * (n - 1)) / n
    gs = fig.add_gridspec(n, 3, left=0.75 / w, right=1 - 0.2 / w, top=1 - top / h, bottom=0.6 / h, wspace=0.25,
                          hspace=0.35 / cell)
    lim_names = list(limits.joint_names)
    first = None
    for k, row in enumerate(rows):
        j, e = names.index(row), lim_names.index(row)
        units = motion_units(robot, row)
        q, v, a = (np.asarray(x, float)[idx, j] for x in (traj.q, traj.v, traj.a))
        exc = [(limits.lower[e], limits.upper[e]), (-limits.velocity[e], limits.velocity[e]),
               (-limits.acceleration[e], limits.acceleration[e])]
        robot_lim = [(None, None)] * 3
        if hard is not None:
            robot_lim = [(hard["lower"][e], hard["upper"][e]), (-hard["velocity"][e], hard["velocity"][e]), (None, None)]
        used = [(q.max() - q.min()) / (exc[0][1] - exc[0][0]), np.abs(v).max() / exc[1][1], np.abs(a).max() / exc[2][1]]
        for c, (x, sym) in enumerate(zip((q, v, a), ("q", "v", "v̇"))):
            ax = fig.add_subplot(gs[k, c], sharex=first)
            first = first or ax
            ax.plot(t, x, color="C0", lw=1.0, zorder=3, gid="trajectory")
            for y in exc[c]:
                ax.axhline(y, color="C1", ls="--", lw=1.0, zorder=2, gid="excitation_limit")
            for y in robot_lim[c]:
                if y is not None and np.isfinite(y):
                    ax.axhline(y, color="C3", lw=1.2, zorder=2, gid="robot_limit")
            ax.set_ylabel(f"{sym} [{units[c]}]", fontsize=7)
            ax.tick_params(labelsize=7)
            share = f"{100 * used[c]:.0f} % of the excitation {'range' if c == 0 else 'limit'}"
            ax.set_title(f"{row}: {share}" if c == 0 else share, fontsize=7, loc="left", y=1.0)
            if k == n - 1:
                ax.set_xlabel("time [s]", fontsize=8)
            else:
                ax.tick_params(labelbottom=False)
    handles = [Line2D([], [], color="C0", lw=1.0), Line2D([], [], color="C1", ls="--", lw=1.0),
               Line2D([], [], color="C3", lw=1.2)]
    labels = ["exported trajectory", "excitation limits", "robot model limits"]
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.12 / h, va="top")
    figure_legend(fig, handles, labels, top_in=top - 0.65, ncol=3)
    return fig


def plot_excitation(traj, limits, out_dir: "str | Path", hard: dict | None = None, *, robot=None,
                    stem: str = "excitation", title: str = "") -> dict[Path, object]:
    """:func:`excitation_figure` per limb of ``robot`` into ``out_dir``: ``STEM.png`` for one limb,
    else ``STEM_<limb>.png``. Returns {path: figure}."""
    groups = limb_groups(robot, list(traj.joint_names))
    paths = grouped_paths(out_dir, stem, groups)
    return {save_figure(fig, paths[g]): fig for g, fig in
            ((g, excitation_figure(traj, limits, hard, robot=robot, rows=members,
                                   title=f"{title}: {g}" if g and title else title or g))
             for g, members in groups.items())}

"""``monitor.png``: the external torque per joint against time, with its contact threshold and
the intervals the monitor reported.

Per monitored row one panel: the reported external torque τ_ext (itself a residual,
τ_measured − τ_model, through the momentum observer), the band inside which a sample is no
contact (shaded, bounded by dashed threshold lines: ±kσ in motion, widened at rest by the
static-friction dead zone; :meth:`~sensorless.estimation.static_band.MonitorTrace.contact_bounds`),
and vertical bands over the reported contact intervals (red), the intervals at rest that static
friction explains (orange), the observer's warm-up (grey) and the quiet window the thresholds
came from (blue). Long logs keep each bucket's extremes (a short contact peak survives). A robot
with several limbs is drawn one limb per figure (``monitor_<limb>.png``, :mod:`.rows`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .figure_kit import envelope_indices, figure_legend, new_figure, runs_of, save_figure, shade_intervals
from .rows import effort_unit, grouped_paths, limb_groups

__all__ = ["monitor_figure", "plot_monitor"]

SPANS = {"contact": ("C3", 0.28, "contact (reported)"), "static_band": ("C1", 0.22, "at rest, within static friction"),
         "warmup": ("0.5", 0.25, "observer warm-up"), "quiet": ("C0", 0.08, "quiet window (thresholds)")}


def monitor_figure(mon, *, robot=None, rows: Sequence[str] | None = None, title: str = "", max_points: int = 4000):
    """The figure (module docstring) of a :class:`~sensorless.estimation.monitoring.MonitorResult`
    for ``rows`` (default every monitored row); units from ``robot`` (:func:`~.rows.effort_unit`)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    names = list(mon.names)
    rows = names if rows is None else list(rows)
    th = mon.thresholds
    t0 = float(mon.t[0])
    t = np.asarray(mon.t, float) - t0
    lo, hi = mon.trace.contact_bounds(mon.raw, th)
    tau = mon.trace.tau_ext
    warm = float(mon.settings.get("warmup_s", 0.0))
    spans = {"contact": [(iv.start - t0, iv.end - t0) for iv in mon.contacts],
             "static_band": [(iv.start - t0, iv.end - t0) for iv in mon.static_band],
             "warmup": [(0.0, warm)] if warm > 0 else [],
             "quiet": [(t[a], t[b]) for a, b in runs_of(mon.quiet)]}
    n = len(rows)
    ncols = 1 if n <= 4 else 2
    nr = int(np.ceil(n / ncols))
    top = 0.75 + (0.3 if title else 0.0)
    fig = new_figure(1.0 + 6.6 * ncols, top + 0.6 + 1.6 * nr + 0.45 * (nr - 1))
    w, h = fig.get_figwidth(), fig.get_figheight()
    cell = (h - top - 0.6 - 0.45 * (nr - 1)) / nr
    gs = fig.add_gridspec(nr, ncols, left=0.8 / w, right=1 - 0.2 / w, top=1 - top / h, bottom=0.6 / h, wspace=0.22,
                          hspace=0.45 / cell)
    first = None
    for k, row in enumerate(rows):
        j = names.index(row)
        ax = fig.add_subplot(gs[k % nr, k // nr], sharex=first)
        first = first or ax
        u = effort_unit(robot, row)
        idx = envelope_indices(tau[:, j], max_points)
        ax.fill_between(t[idx], lo[idx, j], hi[idx, j], color="C2", alpha=0.15, lw=0, zorder=1, gid="no_contact_band")
        for b in (lo, hi):
            ax.plot(t[idx], b[idx, j], color="C3", ls="--", lw=0.8, zorder=2, gid="threshold")
        ax.plot(t[idx], tau[idx, j], color="k", lw=0.8, zorder=3, gid="tau_ext")
        for kind, (color, alpha, _) in SPANS.items():
            shade_intervals(ax, spans[kind], color=color, alpha=alpha, gid=kind)
        ax.set_xlim(t[0], t[-1])
        ax.set_ylabel(f"τ_ext [{u}]", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{row}    threshold ±{th.k:.2f} σ: moving σ {th.sigma_move[j]:.3g} {u}, static band "
                     f"±{th.band[j]:.3g} {u} ({th.band_source[j]})", fontsize=7, loc="left", y=1.0)
        if k % nr == nr - 1 or k == n - 1:
            ax.set_xlabel("time [s]", fontsize=8)
        else:
            ax.tick_params(labelbottom=False)
    handles = [Line2D([], [], color="k", lw=0.8), Line2D([], [], color="C3", ls="--", lw=0.8),
               Patch(color="C2", alpha=0.3)]
    labels = ["external torque τ_ext", "contact threshold", "no-contact band"]
    for kind, (color, alpha, label) in SPANS.items():
        if spans[kind]:
            handles.append(Patch(color=color, alpha=min(1.0, 2 * alpha)))
            labels.append(f"{label} ({len(spans[kind])})" if kind in ("contact", "static_band") else label)
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.12 / h, va="top")
    figure_legend(fig, handles, labels, top_in=top - 0.7, ncol=4)
    return fig


def plot_monitor(mon, out_dir: "str | Path", *, robot=None, stem: str = "monitor", title: str = "") -> dict[Path, object]:
    """:func:`monitor_figure` per limb of ``robot`` into ``out_dir``: ``STEM.png`` for one limb, else
    ``STEM_<limb>.png``. Returns {path: figure}."""
    groups = limb_groups(robot, list(mon.names))
    paths = grouped_paths(out_dir, stem, groups)
    return {save_figure(fig, paths[g]): fig for g, fig in
            ((g, monitor_figure(mon, robot=robot, rows=members, title=f"{title}: {g}" if g and title else title or g))
             for g, members in groups.items())}

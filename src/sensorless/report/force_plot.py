"""``estimate-force``'s figure: each Cartesian force (or moment) component against time, with the
samples where it is unobservable marked.

One panel per component (fx, fy, fz [N]; mx, my, mz [N·m]) in the estimate's reference frame.
Where no joint torque measures a component (a singular configuration) the estimate is NaN: the
trace breaks and a red band with a tick under it marks each such run. Light yellow bands mark the
samples solved with damping (σ_min of the Jacobian below its threshold: the estimate is biased
toward zero there). Long logs keep each bucket's extremes and every break of the trace.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figure_kit import envelope_indices, figure_legend, new_figure, runs_of, save_figure, shade_intervals, stride_indices

__all__ = ["force_figure", "plot_force"]


def _unit(label: str) -> str:
    return "N·m" if label.lower().startswith("m") else "N"


def _spans(t: np.ndarray, flag: np.ndarray) -> list[tuple[float, float]]:
    """Time spans of the runs of ``flag``, half a sample wider on each side (a single sample shows)."""
    if len(t) < 2:
        return []
    half = 0.5 * float(np.median(np.diff(t)))
    return [(t[a] - half, t[b] + half) for a, b in runs_of(flag)]


def force_figure(est, *, title: str = "", max_points: int = 4000):
    """The figure (module docstring) of a :class:`~sensorless.estimation.force.ForceEstimate`."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    t = np.asarray(est.t, float) - float(est.t[0])
    F = np.asarray(est.F, float)
    m = F.shape[1]
    unobs = np.zeros(F.shape, bool) if est.unobservable is None else np.asarray(est.unobservable, bool)
    damped = np.asarray(est.damping, float) > 0
    top = 0.7 + (0.3 if title else 0.0)
    fig = new_figure(9.0, top + 0.6 + 1.45 * m + 0.3 * (m - 1))
    w, h = fig.get_figwidth(), fig.get_figheight()
    cell = (h - top - 0.6 - 0.3 * (m - 1)) / m
    gs = fig.add_gridspec(m, 1, left=0.85 / w, right=1 - 0.2 / w, top=1 - top / h, bottom=0.6 / h, hspace=0.3 / cell)
    idx = envelope_indices(np.where(np.isfinite(F), F, 0.0), max_points)
    keep = np.zeros(len(t), bool)
    keep[idx] = True
    for c in range(m):  # the first NaN sample of each unobservable run: the trace breaks there whatever the decimation
        keep[[a for a, _ in runs_of(unobs[:, c])]] = True
    sel = np.flatnonzero(keep)
    first = None
    for c, label in enumerate(est.labels):
        ax = fig.add_subplot(gs[c, 0], sharex=first)
        first = first or ax
        ax.plot(t[sel], F[sel, c], color="C0", lw=0.9, zorder=3, gid="force")
        shade_intervals(ax, _spans(t, damped), color="gold", alpha=0.25, gid="damped")
        spans = _spans(t, unobs[:, c])
        shade_intervals(ax, spans, color="C3", alpha=0.3, gid="unobservable", zorder=1)
        if spans:  # one tick per unobservable sample (every k-th of them in a long log)
            at = np.flatnonzero(unobs[:, c])
            at = at[stride_indices(at.size, max_points)]
            ax.plot(t[at], np.zeros(at.size), "|", color="C3", ms=6,
                    transform=ax.get_xaxis_transform(), clip_on=False, zorder=4, gid="unobservable_samples")
        ax.set_xlim(t[0], t[-1])
        ax.set_ylabel(f"{label} [{_unit(label)}]", fontsize=8)
        ax.tick_params(labelsize=7)
        n_u = int(unobs[:, c].sum())
        ax.set_title(f"{label}: {n_u} of {len(t)} samples unobservable" if n_u else f"{label}: observable on every sample",
                     fontsize=7, loc="left", y=1.0)
        if c < m - 1:
            ax.tick_params(labelbottom=False)
    first.figure.axes[-1].set_xlabel("time [s]", fontsize=8)
    handles, labels = [Line2D([], [], color="C0", lw=0.9)], [f"force at {est.frame} ({est.reference})"]
    if unobs.any():
        handles.append(Patch(color="C3", alpha=0.5))
        labels.append("unobservable (NaN: no joint torque measures it)")
    if damped.any():
        handles.append(Patch(color="gold", alpha=0.5))
        labels.append("damped (near a singularity)")
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.12 / h, va="top")
    figure_legend(fig, handles, labels, top_in=top - 0.65, ncol=3)
    return fig


def plot_force(est, path: "str | Path", *, title: str = ""):
    """:func:`force_figure` written to ``path`` (PNG); returns the figure."""
    fig = force_figure(est, title=title)
    save_figure(fig, path)
    return fig

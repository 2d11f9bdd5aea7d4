"""Measured against predicted joint torques, with the residual of each model under each joint.

Per row (joint, or a floating base's force/moment row) two panels share the time axis: the
measured effort (a wide translucent grey band) and each model's prediction on top of it in its
own colour, line style, width and z-order (two close models stay distinguishable: the first is a
wide translucent line, the later ones thin, dashed or dotted, over it), and below it the residual τ_measured − τ_model per model,
about a zero line. Each row's title gives the RMSE per model in the row's unit. One legend
above the axes. Rows of a robot with several limbs go one limb per figure (:mod:`.rows`):
:func:`plot_torques_by_limb` writes ``torques.png``, or ``torques_<limb>.png`` per limb.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .figure_kit import figure_legend, new_figure, paired_axes, save_figure, stride_indices
from .rows import effort_unit, grouped_paths, limb_groups

__all__ = ["plot_torques", "plot_torques_by_limb", "torque_axes", "torque_figure"]

#: (colour, line style, width, alpha) per model, in order, each drawn over the previous: the first is a wide
#: translucent line, the later ones thinner and dashed or dotted, so two equal traces show as a line on a halo
MODEL_STYLES = [("C0", "-", 2.4, 0.6), ("C3", "--", 1.0, 1.0), ("C2", ":", 1.4, 1.0), ("C1", "-.", 0.9, 1.0),
                ("C4", (0, (5, 1, 1, 1)), 0.9, 1.0), ("C5", (0, (1, 2)), 1.2, 1.0)]
_QUANTITY = {"N·m": "torque", "N": "force"}
MEASURED_STYLE = dict(color="0.2", lw=3.0, alpha=0.3, zorder=2, solid_capstyle="butt")


def _style(k: int) -> dict:
    c, ls, lw, alpha = MODEL_STYLES[k % len(MODEL_STYLES)]
    return dict(color=c, ls=ls, lw=lw, alpha=alpha, zorder=3 + k)


def _grid(n: int, title: bool) -> tuple[int, int, float]:
    """(columns, rows of panels per column, top margin [in]) of the figure for ``n`` rows."""
    ncols = 1 if n <= 4 else 2
    return ncols, int(np.ceil(n / ncols)), 0.6 + (0.3 if title else 0.0)


def torque_axes(n: int, title: bool = True):
    """The empty figure of :func:`torque_figure` for ``n`` rows (with room for a title): ``(fig, pairs)``,
    a (signal, residual) pair of axes per row. It depends on the row count only, so a figure process
    can build (and draw once) it before the data exist."""
    ncols, nr, top = _grid(n, title)
    fig = new_figure(1.0 + 6.6 * ncols, top + 0.6 + 1.95 * nr + 0.45 * (nr - 1))
    pairs, _ = paired_axes(fig, n, ncols, left=0.8, right=0.2, top=top, bottom=0.6, wspace=0.22)
    return fig, pairs


def torque_figure(t: np.ndarray, measured: np.ndarray, predictions: dict[str, np.ndarray], rows: Sequence[str], *,
                  robot=None, units: Sequence[str] | None = None, title: str = "", max_points: int = 4000,
                  axes=None):
    """The figure (module docstring) for ``rows`` (columns of ``measured`` and of each prediction).
    Units per row from ``units`` or ``robot`` (:func:`~.rows.effort_unit`); time in s from the
    first sample; at most ``max_points`` samples (every k-th). ``axes``: a ``(fig, pairs)`` of
    :func:`torque_axes` for these rows, drawn into instead of a new one."""
    t = np.asarray(t, float)
    idx = stride_indices(len(t), max_points)
    t = t[idx] - t[0]
    measured = np.asarray(measured, float)[idx]
    preds = {k: np.asarray(v, float)[idx] for k, v in predictions.items()}
    rows = list(rows)
    n = len(rows)
    units = list(units) if units is not None else [effort_unit(robot, r) for r in rows]
    fig, pairs = axes if axes is not None else torque_axes(n, bool(title))
    _, nr, top = _grid(n, bool(title))
    handles = labels = None
    for j, (ax, res) in enumerate(pairs):
        u = units[j]
        ax.plot(t, measured[:, j], label="measured", **MEASURED_STYLE)
        res.axhline(0.0, color="0.5", lw=0.8, zorder=1)
        rms = []
        for k, (name, p) in enumerate(preds.items()):
            ax.plot(t, p[:, j], label=name, **_style(k))
            r = measured[:, j] - p[:, j]
            res.plot(t, r, label=name, **_style(k))
            rms.append(f"{name} {np.sqrt(np.nanmean(r**2)):.3g}")
        ax.set_title(f"{rows[j]}    RMSE: {', '.join(rms)} {u}", fontsize=8, loc="left", y=1.0)
        ax.set_ylabel(f"{_QUANTITY.get(u, 'effort')} [{u}]", fontsize=7)
        res.set_ylabel(f"residual [{u}]", fontsize=7)
        if handles is None:
            handles, labels = ax.get_legend_handles_labels()
        if j % nr == nr - 1 or j == n - 1:
            res.set_xlabel("time [s]", fontsize=8)
        else:
            res.tick_params(labelbottom=False)
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.12 / fig.get_figheight(), va="top")
    if handles:
        figure_legend(fig, handles, labels, top_in=top - 0.5)
    return fig


def plot_torques(t: np.ndarray, measured: np.ndarray, predictions: dict[str, np.ndarray], joints: list[str],
                 path: "str | Path | None" = None, title: str = "", *, robot=None, units: Sequence[str] | None = None,
                 axes=None):
    """:func:`torque_figure` of every row in one figure (into ``axes`` if given), written to ``path``
    (PNG) if given; returns it."""
    fig = torque_figure(t, measured, predictions, joints, robot=robot, units=units, title=title, axes=axes)
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_torques_by_limb(t: np.ndarray, measured: np.ndarray, predictions: dict[str, np.ndarray], rows: Sequence[str],
                         out_dir: "str | Path", *, robot=None, stem: str = "torques", title: str = "") -> dict[Path, object]:
    """One :func:`torque_figure` per limb of ``robot`` (:func:`~.rows.limb_groups`) in ``out_dir``:
    ``STEM.png`` for a robot with one limb, else ``STEM_<limb>.png``. Returns {path: figure}."""
    rows = list(rows)
    groups = limb_groups(robot, rows)
    paths = grouped_paths(out_dir, stem, groups)
    out = {}
    measured = np.asarray(measured)
    for g, members in groups.items():
        cols = [rows.index(m) for m in members]
        fig = torque_figure(t, measured[:, cols], {k: np.asarray(v)[:, cols] for k, v in predictions.items()}, members,
                            robot=robot, title=f"{title}: {g}" if g and title else title or g)
        out[save_figure(fig, paths[g])] = fig
    return out

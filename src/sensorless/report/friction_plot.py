"""``identify``'s friction.png: friction against velocity per joint, with its residual.

Per term joint (actuated, then passive) two panels share the velocity axis: the torque the
rigid-body + armature model leaves to friction, r = τ − [Y π]_j − Ia_j v̇_j (grey dots, at most
``max_points`` samples drawn at random with a fixed seed; only those samples are evaluated, so the
figure costs the same on any length of log), with the identified steady friction
curve τ_f(v) (:func:`~sensorless.identification.friction.friction_curve`); and below it the
residual r − τ_f(v) of each dot. Units per joint (N·m against rad/s, or N against m/s); one
legend above the axes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from .figure_kit import figure_legend, new_figure, paired_axes, save_figure
from .rows import effort_unit, motion_units

__all__ = ["draw_friction", "friction_axes", "friction_figure", "friction_panels", "plot_friction", "plot_friction_panels"]


def friction_figure(structure, params: np.ndarray, logs: Iterable, title: str = "", max_points: int = 4000):
    """The figure (module docstring) of the identified ``params`` of ``structure`` on ``logs``."""
    return draw_friction(**friction_panels(structure, params, logs, max_points), title=title)


def friction_panels(structure, params: np.ndarray, logs: Iterable, max_points: int = 4000) -> dict:
    """What :func:`draw_friction` draws, as arrays and strings (no model): the dots (v, r) of at
    most ``max_points`` samples drawn at random (seed 0) from ``logs``, the curve on a velocity
    grid, the residuals, and each joint's labels. When every term is pointwise in the sample (no
    ``presliding`` state) only the drawn samples are evaluated."""
    from ..identification.friction import friction_curve, friction_residual

    logs = list(logs)
    N = sum(len(t) for t in logs)
    if N > max_points and "presliding" not in structure.joint_terms:
        idx = np.random.default_rng(0).choice(N, max_points, replace=False)
        pick, starts = np.sort(idx), np.cumsum([0] + [len(t) for t in logs])
        parts = [(t, pick[(pick >= a) & (pick < b)] - a) for t, a, b in zip(logs, starts[:-1], starts[1:])]
        pairs = [friction_residual(structure, params, t.take(k)) for t, k in parts if len(k)]
        order = np.searchsorted(pick, idx)
        V = np.concatenate([v for v, _ in pairs])[order]
        R = np.concatenate([r for _, r in pairs])[order]
    else:
        pairs = [friction_residual(structure, params, t) for t in logs]
        V = np.concatenate([v for v, _ in pairs])
        R = np.concatenate([r for _, r in pairs])
        if len(V) > max_points:
            idx = np.random.default_rng(0).choice(len(V), max_points, replace=False)
            V, R = V[idx], R[idx]
    joints = list(structure.robot.term_joints)  # actuated, then passive (τ = 0)
    n = len(joints)
    vmax = np.nanmax(np.abs(V), axis=0) if len(V) else np.ones(n)
    grid = np.linspace(-1.0, 1.0, 801)[:, None] * np.where(vmax > 0, vmax, 1.0)[None, :]
    curve = friction_curve(structure, params, grid)
    resid = R - friction_curve(structure, params, V) if len(V) else R
    robot = structure.robot
    labels = []
    for j in joints:
        tu, vu = effort_unit(robot, j), motion_units(robot, j)[1]
        eps = structure.smoothing_of(j)
        terms = ",".join(t for t in structure.terms_of(j) if t != "armature")
        vs = (structure.stribeck_velocity or {}).get(j)
        labels.append((f"{j}: {terms}; w = {eps:.3g} {vu}" + (f", vs = {vs:.3g} {vu}" if vs else ""), tu, vu))
    return dict(V=V, R=R, grid=grid, curve=curve, resid=resid, labels=labels)


def _top(title: bool) -> float:
    """The top margin [in] of the figure: the legend, and the title when there is one."""
    return 0.55 + (0.3 if title else 0.0)


def friction_axes(n: int, title: bool = True):
    """The empty figure of :func:`draw_friction` for ``n`` joints: ``(fig, pairs)`` (it depends on the
    joint count only, so a figure process can build and draw it before the data exist)."""
    cols = 3 if n > 4 else n
    top = _top(title)
    nr = int(np.ceil(n / cols))
    fig = new_figure(0.6 + 4.0 * cols, top + 0.55 + 2.6 * nr + 0.55 * (nr - 1))
    axes, _ = paired_axes(fig, n, cols, left=0.75, right=0.15, top=top, bottom=0.55, wspace=0.32, gap=0.55,
                          share_all=False, by_rows=True)
    return fig, axes


def draw_friction(V: np.ndarray, R: np.ndarray, grid: np.ndarray, curve: np.ndarray, resid: np.ndarray,
                  labels: list, title: str = "", axes=None):
    """The figure of :func:`friction_panels`' arrays; ``labels`` per joint: (title, effort unit, velocity unit).
    ``axes``: a ``(fig, pairs)`` of :func:`friction_axes` for as many joints, drawn into."""
    n = len(labels)
    top = _top(bool(title))
    fig, axes = axes if axes is not None else friction_axes(n, bool(title))
    for k, (label, tu, vu) in enumerate(labels):
        ax, res = axes[k]
        ax.plot(V[:, k], R[:, k], ".", ms=1.5, color="0.6", label="τ − rigid body (samples)", zorder=2)
        ax.plot(grid[:, k], curve[:, k], color="C3", lw=1.4, label="identified friction τ_f(v)", zorder=3)
        res.axhline(0.0, color="C3", lw=0.8, zorder=1)
        res.plot(V[:, k], resid[:, k], ".", ms=1.2, color="0.4", zorder=2)
        ax.set_title(label, fontsize=7, loc="left", y=1.0)
        ax.set_ylabel(f"friction [{tu}]", fontsize=7)
        res.set_ylabel(f"residual [{tu}]", fontsize=7)
        res.set_xlabel(f"v [{vu}]", fontsize=7)
    handles, labels = axes[0][0].get_legend_handles_labels()
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.1 / fig.get_figheight(), va="top")
    figure_legend(fig, handles, labels, top_in=top - 0.5, markerscale=4)
    return fig


def plot_friction(structure, params: np.ndarray, logs: Iterable, path: "str | Path | None" = None, title: str = "",
                  max_points: int = 4000):
    """:func:`friction_figure`, written to ``path`` (PNG) if given; returns the figure."""
    fig = friction_figure(structure, params, logs, title=title, max_points=max_points)
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_friction_panels(panels: dict, path: "str | Path", axes=None):
    """:func:`draw_friction` of ``panels`` (:func:`friction_panels`, with its ``title``) written to ``path``
    (into ``axes`` of :func:`friction_axes` if given)."""
    fig = draw_friction(**panels, axes=axes)
    save_figure(fig, path)
    return fig

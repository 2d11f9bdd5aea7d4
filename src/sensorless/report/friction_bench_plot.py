"""``sensorless friction``'s friction.png: a bench model's friction against velocity and around a
reversal, each panel with its residual below (Agg figure, :mod:`.figure_kit`).

Per joint of a :class:`~sensorless.identification.friction_model.FrictionModel`, three panels:

* the friction τ − J v̇ of ``logs`` (grey dots, at most ``max_points``) against velocity, with the
  chosen law along the first log (its loops are the hysteresis) and the best static law's curve;
* the same around v = 0 (|v| ≤ 5 % of P95 |v|: presliding);
* τ against time around the first reversal of the first log: measured, chosen law and static law.

Below each, the residual of the first log: measured − chosen law (and − static law on the right).
A drive's friction is what its drive terms deliver minus the output torque
(:meth:`~sensorless.identification.friction_model.FrictionModel.friction_pair`).
Units as the command's (N·m, rad/s; a linear axis reads N, m/s); one legend above the axes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .figure_kit import figure_legend, new_figure, paired_axes, save_figure

__all__ = ["bench_friction_figure", "plot_bench_friction"]

TU, VU = "N·m", "rad/s"


def bench_friction_figure(model, logs: Sequence, *, window: float = 1.0, max_points: int = 6000, title: str = ""):
    """The figure (module docstring)."""
    from matplotlib.lines import Line2D

    from ..identification.friction_model import reversal_mask

    joints = list(model.joint_names_)
    n = len(joints)
    top = 0.6 + (0.3 if title else 0.0)
    fig = new_figure(13.0, top + 0.55 + 3.0 * n + 0.55 * (n - 1))
    axes, _ = paired_axes(fig, 3 * n, 3, left=0.75, right=0.15, top=top, bottom=0.55, wspace=0.3, gap=0.55,
                          share_all=False, by_rows=True)
    rng = np.random.default_rng(0)
    first = logs[0]
    meas1, pred = model.friction_pair(first)
    stat = model.friction_pair(first, static=True)[1] if model.static_laws_ else None
    measured = [model.friction_pair(tr)[0] for tr in logs]
    any_static = False
    for k, j in enumerate(joints):
        law = model.laws_[j]
        J = law.coef.get("inertia", 0.0)
        V, F = [], []
        for tr, mf in zip(logs, measured):
            c = list(tr.joint_names).index(j)
            V.append(tr.v[:, c])
            F.append(mf[:, k] - (J * tr.a[:, c] if J and tr.a is not None else 0.0))
        V, F = np.concatenate(V), np.concatenate(F)
        pick = rng.choice(V.size, min(V.size, max_points), replace=False)
        c = list(first.joint_names).index(j)
        v1 = first.v[:, c]
        inertial = J * first.a[:, c] if J and first.a is not None else 0.0
        own = pred[:, k] - inertial
        f1 = meas1[:, k] - inertial
        pick1 = rng.choice(v1.size, min(v1.size, max_points), replace=False)
        speed = float(np.percentile(np.abs(V), 95)) or 1.0
        for col, lim in ((0, 1.05 * float(np.max(np.abs(V)))), (1, 0.05 * speed)):
            ax, res = axes[3 * k + col]
            ax.plot(V[pick], F[pick], ".", ms=1.5, color="0.7", label="measured τ − J v̇", zorder=2)
            ax.plot(v1, own, lw=0.7, color="C0", label="chosen law along the log", zorder=3)
            if j in model.static_laws_:
                any_static = True
                grid = np.linspace(-lim, lim, 801)
                ax.plot(grid, model.static_laws_[j].steady(grid), "--", lw=1.0, color="C3", label="best static law",
                        zorder=4)
            res.axhline(0.0, color="C0", lw=0.8, zorder=1)
            res.plot(v1[pick1], (f1 - own)[pick1], ".", ms=1.2, color="0.4", zorder=2)
            ax.set_xlim(-lim, lim)
            ax.set_ylabel(f"friction [{TU}]", fontsize=7)
            res.set_ylabel(f"residual [{TU}]", fontsize=7)
            res.set_xlabel(f"v [{VU}]", fontsize=7)
        axes[3 * k][0].set_title(f"{j}: {law.kind} law", fontsize=8, loc="left", y=1.0)
        axes[3 * k + 1][0].set_title("near v = 0", fontsize=8, loc="left", y=1.0)
        ax, res = axes[3 * k + 2]
        m = reversal_mask(first.t, v1, window=window)
        ax.set_title("first reversal", fontsize=8, loc="left", y=1.0)
        if m.any():
            i0 = int(np.flatnonzero(m)[0])
            i1 = i0 + int(np.flatnonzero(~m[i0:])[0]) if (~m[i0:]).any() else m.size
            sl = slice(i0, i1)
            ts = first.t[sl] - first.t[0]
            ax.plot(ts, meas1[sl, k], color="0.5", lw=1.0, zorder=2)
            ax.plot(ts, pred[sl, k], color="C0", lw=1.0, zorder=3)
            res.axhline(0.0, color="0.5", lw=0.8, zorder=1)
            res.plot(ts, meas1[sl, k] - pred[sl, k], color="C0", lw=0.9, zorder=3)
            if stat is not None and law.kind == "state":
                ax.plot(ts, stat[sl, k], "--", color="C3", lw=1.0, zorder=4)
                res.plot(ts, meas1[sl, k] - stat[sl, k], "--", color="C3", lw=0.9, zorder=4)
        else:
            ax.text(0.5, 0.5, "no reversal in the log", transform=ax.transAxes, ha="center", va="center", fontsize=8)
        ax.set_ylabel(f"τ [{TU}]", fontsize=7)
        res.set_ylabel(f"residual [{TU}]", fontsize=7)
        res.set_xlabel("time [s]", fontsize=7)
    handles = [Line2D([], [], ls="", marker=".", ms=6, color="0.7"), Line2D([], [], color="0.5", lw=1.0),
               Line2D([], [], color="C0", lw=1.0)]
    labels = ["measured friction τ − J v̇ (samples)", "measured τ", "chosen law (state or static)"]
    if any_static:
        handles.append(Line2D([], [], color="C3", ls="--", lw=1.0))
        labels.append("best static law")
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.1 / fig.get_figheight(), va="top")
    figure_legend(fig, handles, labels, top_in=top - 0.55)
    return fig


def plot_bench_friction(model, logs: Sequence, path: "str | Path", *, window: float = 1.0, max_points: int = 6000,
                        title: str = ""):
    """:func:`bench_friction_figure` written to ``path`` (PNG); returns the figure."""
    fig = bench_friction_figure(model, logs, window=window, max_points=max_points, title=title)
    save_figure(fig, path)
    return fig

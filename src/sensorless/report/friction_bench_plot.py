"""Friction of a bench model against velocity and around a reversal (Agg backend, files only)."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["plot_bench_friction"]


def plot_bench_friction(model, logs: Sequence, path: "str | Path", *, window: float = 1.0, max_points: int = 6000,
                        title: str = "") -> None:
    """Per joint of a :class:`~sensorless.identification.friction_model.FrictionModel`, three panels:
    the friction τ − J v̇ of ``logs`` (grey dots) against velocity with the chosen law along the
    first log (its loops are the hysteresis) and the best static law's curve; the same around v = 0
    (|v| ≤ 5 % of P95 |v|: presliding); and τ against time around the first reversal of the first
    log, measured, chosen law and static law."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..identification.friction_model import reversal_mask

    joints = list(model.joint_names_)
    fig, axes = plt.subplots(len(joints), 3, figsize=(12, 3.2 * len(joints) + 0.5), squeeze=False)
    rng = np.random.default_rng(0)
    first = logs[0]
    pred = model.predict(first)
    stat = model.predict(first, static=True) if model.static_laws_ else None
    for k, j in enumerate(joints):
        law = model.laws_[j]
        J = law.coef.get("inertia", 0.0)
        V, F = [], []
        for tr in logs:
            c = list(tr.joint_names).index(j)
            V.append(tr.v[:, c])
            F.append(tr.tau[:, c] - (J * tr.a[:, c] if J and tr.a is not None else 0.0))
        V, F = np.concatenate(V), np.concatenate(F)
        pick = rng.choice(V.size, min(V.size, max_points), replace=False)
        c = list(first.joint_names).index(j)
        v1 = first.v[:, c]
        own = pred[:, k] - (J * first.a[:, c] if J and first.a is not None else 0.0)
        speed = float(np.percentile(np.abs(V), 95)) or 1.0
        for ax, lim in ((axes[k, 0], 1.05 * float(np.max(np.abs(V)))), (axes[k, 1], 0.05 * speed)):
            ax.plot(V[pick], F[pick], ".", ms=1.5, color="0.7", label="measured τ − J v̇")
            ax.plot(v1, own, lw=0.7, color="C0", label=f"{law.kind} law along the log")
            if j in model.static_laws_:
                grid = np.linspace(-lim, lim, 801)
                ax.plot(grid, model.static_laws_[j].steady(grid), "--", lw=1.0, color="C3", label="best static law")
            ax.set_xlim(-lim, lim)
            ax.set_xlabel("v")
            ax.set_ylabel(f"{j}: friction")
        axes[k, 1].set_title("near v = 0", fontsize=9)
        axes[k, 0].legend(fontsize=7, loc="best")
        ax = axes[k, 2]
        m = reversal_mask(first.t, v1, window=window)
        if m.any():
            i0 = int(np.flatnonzero(m)[0])
            i1 = i0 + int(np.flatnonzero(~m[i0:])[0]) if (~m[i0:]).any() else m.size
            sl = slice(i0, i1)
            ax.plot(first.t[sl], first.tau[sl, c], color="0.5", lw=1.0, label="measured")
            ax.plot(first.t[sl], pred[sl, k], color="C0", lw=1.0, label=law.kind)
            if stat is not None and law.kind == "state":
                ax.plot(first.t[sl], stat[sl, k], "--", color="C3", lw=1.0, label="static")
            ax.legend(fontsize=7)
        ax.set_xlabel("t [s]")
        ax.set_title("first reversal", fontsize=9)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

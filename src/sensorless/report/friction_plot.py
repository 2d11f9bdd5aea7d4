"""Friction against velocity, one panel per actuated joint (Agg backend, files only)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

__all__ = ["plot_friction"]


def plot_friction(structure, params: np.ndarray, logs: Iterable, path: str | Path, title: str = "",
                  max_points: int = 4000) -> None:
    """Per joint: the torque the rigid-body + armature model leaves to friction,
    r = τ − [Y π]_j − Ia_j v̇_j (grey dots, at most ``max_points``), and the identified
    friction curve τ_f(v) (:func:`~sensorless.identification.friction.friction_curve`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..identification.friction import friction_curve, friction_residual

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
    cols = 3 if n > 4 else n
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 2.6 * rows + 0.6), squeeze=False)
    for k, ax in enumerate(axes.ravel()):
        if k >= n:
            ax.axis("off")
            continue
        ax.plot(V[:, k], R[:, k], ".", ms=1.5, color="0.6", label="τ − rigid body")
        ax.plot(grid[:, k], curve[:, k], color="C3", lw=1.4, label="identified friction")
        eps = structure.smoothing_of(joints[k])
        terms = ",".join(t for t in structure.terms_of(joints[k]) if t != "armature")
        vs = (structure.stribeck_velocity or {}).get(joints[k])
        ax.set_title(f"{joints[k]}\n{terms}; w={eps:.3g}" + (f", vs={vs:.3g}" if vs else ""), fontsize=7)
        ax.set_xlabel("v", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[0, 0].set_ylabel("torque", fontsize=7)
    axes[0, 0].legend(fontsize=6, loc="upper left")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

"""Matplotlib figures (Agg backend, files only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_torques"]


def plot_torques(
    t: np.ndarray,
    measured: np.ndarray,
    predictions: dict[str, np.ndarray],
    joints: list[str],
    path: str | Path,
    title: str = "",
) -> None:
    """Measured vs predicted effort, one panel per joint."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(joints)
    height = 1.6 * n + 0.8
    fig, axes = plt.subplots(n, 1, figsize=(9, height), sharex=True, squeeze=False)
    t = np.asarray(t) - t[0]
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(t, measured[:, j], color="k", lw=1.0, label="measured")
        for name, pred in predictions.items():
            ax.plot(t, pred[:, j], lw=0.9, label=name)
        ax.set_ylabel(joints[j], fontsize=7)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, ncol=len(predictions) + 1, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title, fontsize=9)
    # fixed margins in inches: tight_layout renders the figure once more just to measure it (~0.3 s)
    fig.subplots_adjust(left=0.9 / 9, right=1 - 0.15 / 9, bottom=0.5 / height, top=1 - (0.4 if title else 0.15) / height,
                        hspace=0.12)
    fig.savefig(path, dpi=110)
    plt.close(fig)

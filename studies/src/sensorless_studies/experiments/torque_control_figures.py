"""Figures of the torque-control study (:mod:`.torque_control`): torque estimation, actuator
fits, swing tracking, force tracking and the open-loop run (PNG files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..simulation.leg_model import JOINTS
from ..simulation.leg_protocols import Q_AIR

__all__ = ["figures", "tracking_figure"]

SHORT = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")


def tracking_figure(plt, t: np.ndarray, q_ref: np.ndarray, logs: dict):
    """Tracking error per joint against time, one line per controller in ``logs`` (``q_true``)."""
    fig, axs = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for j, ax in enumerate(axs.T.ravel()):
        for name, style in (("position", "k-"), ("torque_p_K6=1", "r-"), ("torque_p_K6=0.25", "g-"), ("torque_pi_K6=0.25", "b--")):
            if name in logs:
                ax.plot(t, np.degrees(q_ref[:, j] - logs[name].q_true[:, j]), style, lw=0.8, label=name)
        ax.set_title(SHORT[j])
        ax.set_ylabel("error [deg]")
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    axs[0, 0].legend(fontsize=7)
    return fig


def figures(out: Path, est_fig, fit_fig, track, force, openl, models) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []

    def save(fig, name: str) -> None:
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        files.append(name)

    # estimator
    t, tau, tau_hat = est_fig
    fig, axs = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for j, ax in enumerate(axs.T.ravel()):
        ax.plot(t, tau[:, j], "k", lw=1, label="true")
        ax.plot(t, tau_hat[:, j], "r--", lw=1, label="F/T + IMU estimate")
        ax.set_title(SHORT[j])
        ax.set_ylabel("Nm")
    axs[0, 0].legend()
    save(fig, "estimator.png")
    # fits
    tau, dq, y = fit_fig
    fig, axs = plt.subplots(2, 3, figsize=(13, 7))
    for j, ax in enumerate(axs.ravel()):
        idx = np.random.default_rng(0).choice(tau.shape[0], min(6000, tau.shape[0]), replace=False)
        ax.scatter(tau[idx, j], 1e3 * (y[idx, j] - models["asymmetric"].k_v[j] * dq[idx, j]), s=1, c="0.6")
        xs = np.linspace(tau[:, j].min(), tau[:, j].max(), 50)
        for name, style in (("least_squares", "b-"), ("asymmetric", "r-")):
            m = models[name]
            ax.plot(xs, 1e3 * m.k_tau[j] * xs, style, label=f"{name}: Kτ={m.k_tau[j]:.2e}")
        ax.set_title(SHORT[j])
        ax.set_xlabel("τ̂ [Nm]")
        ax.set_ylabel("Δq − Kv q̇ [mrad]")
        ax.legend(fontsize=7)
    save(fig, "actuator_fits.png")
    # tracking
    save(tracking_figure(plt, track["t"], track["q_ref"], track["logs"]), "tracking.png")
    # force
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(force["t"], force["f_d"], "k", lw=1.5, label="desired")
    for name, lg in force["logs"].items():
        ax.plot(force["t"], lg.contact[:, 2], lw=0.8, label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vertical contact force [N]")
    ax.legend(fontsize=8)
    save(fig, "force_tracking.png")
    # open loop: travel after release at the highest speed, and the hip-roll release
    summ = openl["summary"]
    fig, axs = plt.subplots(1, 2, figsize=(12, 4))
    key = next(k for k in next(iter(summ.values())) if k.startswith("travel"))
    x = np.arange(6)
    for i, (mname, c) in enumerate((("least_squares", "b"), ("asymmetric", "r"))):
        if mname in summ:
            axs[0].bar(x + (i - 0.5) * 0.4, [summ[mname][key][j] for j in JOINTS], 0.4, color=c, label=mname)
    axs[0].set_xticks(x, SHORT, rotation=20)
    axs[0].set_ylabel("travel after release [deg]")
    axs[0].set_title(key.replace("_", " "))
    axs[0].legend()
    for mname, c in (("least_squares", "b"), ("asymmetric", "r")):
        lg = openl["logs"].get(f"release_{JOINTS[1]}/{mname}")
        if lg is not None:
            axs[1].plot(lg.t, np.degrees(lg.q_true[:, 1] - Q_AIR[1]), c, label=mname)
    axs[1].set_title("hip roll released, zero feedback")
    axs[1].set_xlabel("t [s]")
    axs[1].set_ylabel("deviation [deg]")
    axs[1].legend()
    save(fig, "open_loop.png")
    return files

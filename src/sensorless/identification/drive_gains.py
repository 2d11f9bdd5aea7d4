"""Drive gains τ = K i from two runs of one trajectory, without and with a known payload.

The robot's own torque cancels between the runs (same q, v, v̇; session drift and the
unknown robot model drop out); what is left is the payload's torque, known from its mass
m at frame F (point mass at the CoM c, :func:`~.payload.point_mass_parameters`):

    K_j (i_j,loaded − i_j,unloaded) = [Y_p(q, v, v̇) φ_p]_j + e_j.

The noise is in the currents, not in the known payload torque y_j = [Y_p φ_p]_j, so
per joint d_j = c_j y_j + b_j + ε_j with c_j = 1/K_j (and an offset b_j for a current
offset that changed between the runs) is an ordinary least-squares line with the errors
where they belong (regressing y on d would be biased low by the current noise);
K_j = 1/c_j. The unloaded run is interpolated at the loaded run's times, shifted by the lag
between the two runs measured on the positions (:func:`~sensorless.data.align.pair_logs`:
cross-correlation, then :func:`~sensorless.data.align.clock_offset`; ``align="rows"`` pairs
samples by index instead).

Velocity reversals. Friction jumps by about 2 fs where a joint's velocity changes sign;
the two runs' clocks never line up to the sample (jitter, resampling), so around each
reversal the difference holds a spike ±2 fs/K that correlates with the payload's inertial
torque (∝ v̇, largest there) and biases K (several % on a wrist). The samples within
``reversal_seconds`` (default :data:`REVERSAL_SECONDS`, 0.1 s: a joint accelerating at a few
rad/s² is then past the Stribeck region, whose steep friction slope turns a clock offset of
a millisecond into a torque error) of a sign change of v (in either run) are left out of
that joint's fit, which also drops a joint at rest (v is noise around 0; static friction
there differs between the runs anyway).

Uncertainty. The residual ε is not white (misalignment between the runs, unmodelled
load-dependent friction): an i.i.d. bootstrap is far too narrow. Reported are a moving
block bootstrap (blocks of ``block_seconds``, default: 4 × the lag where the residual
autocorrelation falls below 0.1, at least 1 s) and a Newey–West (HAC) standard error with
the same bandwidth; the 95 % interval is K ± 1.96 · max(both) (delta method 1/c).

Misfit. With the right payload description the residual ε is the current noise (plus a little
misalignment), whatever the gains; a wrong mass, CoM or frame, or two runs that are not one
trajectory, leave the payload torque's shape in ε, and the fitted K absorb part of it (a CoM
off by 10 cm gave gains 0.4–1.2× the truth with every interval narrow). The noise floor σ_n of
each joint's d is measured on the log itself, from its Savitzky–Golay residual, robustly
(:func:`~sensorless.data.rest.signal_noise`);
a joint whose residual RMS exceeds :data:`MAX_MISFIT` σ_n is a misfit (``misfit``,
``diagnostics["residual_over_noise"]``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..data.align import ALIGNMENTS, pair_logs
from ..data.rest import signal_noise
from ..data.trajectory import Trajectory
from ..errors import DataError, ExcitationError, JointNameError
from ..robot import Robot
from .payload_model import payload_regressor, point_mass_parameters

__all__ = ["DriveGains", "identify_drive_gains", "payload_torque"]

#: samples within this time [s] of a velocity reversal are left out of a joint's fit (module docstring)
REVERSAL_SECONDS = 0.1
#: a joint whose gain has a relative std above this is reported as not identified
MAX_RELATIVE_STD = 0.2
#: residual RMS over the log's own current noise above which a joint is a misfit (module docstring)
MAX_MISFIT = 3.0


@dataclass
class DriveGains:
    """Identified gains per actuated joint; ``to_dict()`` is a file that ``--gains`` reads."""

    joints: list[str]
    gains: np.ndarray
    std: np.ndarray
    interval: np.ndarray  # (n, 2) 95 %
    identified: np.ndarray  # bool
    offset: np.ndarray  # current offset b_j [A]
    misfit: np.ndarray | None = None  # bool: residual > MAX_MISFIT × the current noise (module docstring)
    diagnostics: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "gains": dict(zip(self.joints, map(float, self.gains))),
            "interval_95": {j: [float(a), float(b)] for j, (a, b) in zip(self.joints, self.interval)},
            "std": dict(zip(self.joints, map(float, self.std))),
            "identified": dict(zip(self.joints, map(bool, self.identified))),
            "current_offset": dict(zip(self.joints, map(float, self.offset))),
            "misfit": dict(zip(self.joints, map(bool, self.misfit if self.misfit is not None
                                               else np.zeros(len(self.joints), bool)))),
            "diagnostics": self.diagnostics,
            "settings": self.settings,
        }


def payload_torque(robot: Robot, traj: Trajectory, frame: str, mass: float, com=None) -> np.ndarray:
    """Torque (N, n_actuated) of a point mass ``mass`` at ``com`` (frame coordinates) at ``frame``."""
    from ..regressor.terms import in_robot_order

    traj = in_robot_order(robot, traj)
    if traj.v is None or traj.a is None:
        raise DataError("the loaded log needs v and v̇ (logged or derived)", traj.source)
    phi = point_mass_parameters(float(mass), np.zeros(3) if com is None else np.asarray(com, dtype=float))
    Q, V, A = robot.full_configuration(traj.q), robot.full_velocity(traj.v), robot.full_velocity(traj.a)
    return payload_regressor(robot, Q, V, A, frame) @ phi


def _currents(robot: Robot, traj: Trajectory) -> np.ndarray:
    """Actuated currents of a log: its ``current`` extra if any, else its ``tau`` column(s)."""
    cur = (traj.extras or {}).get("current")
    if cur is None:
        cur = traj.tau
    if cur is None:
        raise DataError("the log has no currents (map them to 'tau' or 'current', with no drive gains)", traj.source)
    names = list(traj.joint_names)
    missing = [j for j in robot.actuated_joints if j not in names]
    if missing:
        raise JointNameError(f"the log has no column for joint(s) {missing}", traj.source)
    return np.asarray(cur, dtype=float)[:, [names.index(j) for j in robot.actuated_joints]]


def _near_reversal(v: np.ndarray, width: int) -> np.ndarray:
    """(N, n) bool: within ``width`` samples of a sign change of v (column-wise)."""
    from scipy.ndimage import maximum_filter1d

    s = np.sign(v)
    change = np.zeros(v.shape, dtype=bool)
    change[1:] = s[1:] != s[:-1]
    change[:-1] |= change[1:]
    return maximum_filter1d(change.astype(np.uint8), size=2 * width + 1, axis=0).astype(bool)


def _act_v(robot: Robot, traj: Trajectory) -> "np.ndarray | None":
    if traj.v is None:
        return None
    names = list(traj.joint_names)
    return np.asarray(traj.v, dtype=float)[:, [names.index(j) for j in robot.actuated_joints]]


def _fit(y: np.ndarray, d: np.ndarray, offset: bool) -> tuple[float, float, np.ndarray]:
    X = np.column_stack([y, np.ones_like(y)]) if offset else y[:, None]
    coef, *_ = np.linalg.lstsq(X, d, rcond=None)
    return float(coef[0]), float(coef[1]) if offset else 0.0, d - X @ coef


def _decorrelation_lag(e: np.ndarray) -> int:
    """First lag where the autocorrelation of ``e`` drops below 0.1 (FFT)."""
    e = e - e.mean()
    n = len(e)
    f = np.fft.rfft(e, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[:n]
    ac = ac / ac[0] if ac[0] > 0 else ac
    below = np.flatnonzero(ac < 0.1)
    return int(below[0]) if below.size else n


def _hac_var(y: np.ndarray, e: np.ndarray, L: int, offset: bool, use: "np.ndarray | None" = None) -> float:
    """Newey–West variance of the slope (Bartlett kernel, bandwidth L); samples with
    ``use`` False are zero rows (left out, their time slot kept)."""
    one = np.ones_like(y) if use is None else use.astype(float)
    X = np.column_stack([y, one]) if offset else y[:, None]
    u = X * e[:, None]
    S = u.T @ u
    for lag in range(1, min(L, len(e) - 1) + 1):
        w = 1.0 - lag / (L + 1.0)
        G = u[lag:].T @ u[:-lag]
        S += w * (G + G.T)
    Xi = np.linalg.pinv(X.T @ X)
    return float((Xi @ S @ Xi)[0, 0])


def identify_drive_gains(
    robot: Robot,
    unloaded: Trajectory,
    loaded: Trajectory,
    *,
    payload_mass: float,
    payload_frame: str,
    payload_com=None,
    offset: bool = True,
    align: str = "auto",
    block_seconds: float | None = None,
    n_boot: int = 1000,
    seed: int = 0,
    reversal_seconds: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> DriveGains:
    """Drive gains from an unloaded/loaded pair of logs holding currents (module docstring);
    ``align`` pairs them (:func:`~sensorless.data.align.pair_logs`, one of ``ALIGNMENTS``).
    ``progress(done, n_boot)`` is called every 100 bootstrap resamples and at the last."""
    if not (np.isfinite(payload_mass) and payload_mass > 0):
        raise DataError(f"payload mass must be a positive number of kg, got {payload_mass!r}")
    if align not in ALIGNMENTS:
        raise DataError(f"align must be one of {ALIGNMENTS}, got {align!r}")
    robot.frame_id(payload_frame)
    _currents(robot, unloaded)
    loaded, unloaded, pairing = pair_logs(loaded, unloaded, align)
    i_u, i_l = _currents(robot, unloaded), _currents(robot, loaded)
    y = payload_torque(robot, loaded, payload_frame, payload_mass, payload_com)
    d = i_l - i_u
    n = len(y)
    if n < 50:
        raise ExcitationError(f"only {n} samples of the loaded log overlap the unloaded one; need >= 50")
    dt = float(np.median(np.diff(loaded.t)))
    joints = list(robot.actuated_joints)
    nj = len(joints)
    width = max(1, int(round((REVERSAL_SECONDS if reversal_seconds is None else reversal_seconds) / dt)))
    use = np.ones((n, nj), dtype=bool)  # per joint: away from velocity reversals (module docstring)
    for v in (_act_v(robot, loaded), _act_v(robot, unloaded)):
        if v is not None:
            use &= ~_near_reversal(v, width)
    y, d = np.where(use, y, 0.0), np.where(use, d, 0.0)  # a left-out sample weighs 0 in every sum below
    c, b, res = np.zeros(nj), np.zeros(nj), np.zeros((n, nj))
    yrms0 = np.sqrt(np.mean(y**2, axis=0))
    seen = (yrms0 > 1e-9 * max(float(yrms0.max()), 1e-300)) & (use.sum(0) >= 50)  # no payload torque: no gain
    for k in range(nj):
        u = use[:, k]
        if seen[k]:
            c[k], b[k], r = _fit(y[u, k], d[u, k], offset)
        else:
            c[k], b[k] = np.nan, float(np.mean(d[u, k])) if offset and u.any() else 0.0
            r = d[u, k] - b[k]
        res[u, k] = r
    if block_seconds is None:
        lag = max(_decorrelation_lag(res[:, k]) for k in range(nj))
        L = int(max(4 * lag, round(1.0 / dt)))
    else:
        L = int(max(1, round(block_seconds / dt)))
    L = min(L, max(n // 8, 1))
    # HAC std of c, then of K = 1/c (delta method)
    std_c_hac = np.array([np.sqrt(max(_hac_var(y[:, k], res[:, k], L, offset, use[:, k]), 0.0)) for k in range(nj)])
    # moving block bootstrap on the normal-equation sums of each block start
    rng = np.random.default_rng(seed)
    starts = np.arange(0, n - L + 1)
    n_blocks = int(np.ceil(n / L))
    cs = np.cumsum(np.vstack([np.zeros((1, nj, 5)),
                              np.stack([y * y, y * d, y, d, use.astype(float)], axis=2)]), axis=0)  # (n+1, nj, 5)
    block = cs[starts + L] - cs[starts]  # (n_starts, nj, 5)
    boot_c = np.empty((n_boot, nj))
    np_err = np.errstate(divide="ignore", invalid="ignore")
    np_err.__enter__()
    for i in range(n_boot):
        s = block[rng.integers(0, len(starts), n_blocks)].sum(0)  # (nj, 5)
        syy, syd, sy, sd, sn = s.T
        if offset:
            boot_c[i] = (sn * syd - sy * sd) / np.maximum(sn * syy - sy**2, 1e-300)
        else:
            boot_c[i] = syd / np.maximum(syy, 1e-300)
        if progress is not None and ((i + 1) % 100 == 0 or i + 1 == n_boot):
            progress(i + 1, n_boot)
    std_c_boot = boot_c.std(axis=0, ddof=1)
    np_err.__exit__(None, None, None)
    std_c = np.maximum(std_c_hac, std_c_boot)
    with np.errstate(divide="ignore", invalid="ignore"):
        K = 1.0 / c
        std_K = std_c / c**2
        lo = 1.0 / (c + 1.96 * std_c)
        hi = np.where(c - 1.96 * std_c > 0, 1.0 / (c - 1.96 * std_c), np.inf)
    ident = seen & (c > 0) & (std_c < MAX_RELATIVE_STD * np.abs(c))
    yrms = np.sqrt(np.mean(y**2, axis=0))
    noise = np.array([float(signal_noise(d[use[:, k], k])[0]) if use[:, k].sum() > 13 else np.nan for k in range(nj)])
    res_rms = np.array([float(np.sqrt(np.mean(res[use[:, k], k] ** 2))) if use[:, k].any() else np.nan
                        for k in range(nj)])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = res_rms / noise
    misfit = seen & (ratio > MAX_MISFIT)
    return DriveGains(
        joints=joints, gains=K, std=std_K, interval=np.column_stack([lo, hi]), identified=ident & ~misfit, offset=b,
        misfit=misfit,
        diagnostics={"n_samples": n, "block_samples": L, "block_seconds": L * dt,
                     "alignment": pairing.to_dict(),
                     "samples_used": dict(zip(joints, map(int, use.sum(0)))),
                     "reversal_samples": width,
                     "payload_torque_rms": dict(zip(joints, map(float, yrms))),
                     "residual_rms_current": dict(zip(joints, map(float, res.std(axis=0)))),
                     "current_noise": dict(zip(joints, map(float, noise))),
                     "residual_over_noise": dict(zip(joints, map(float, ratio))),
                     "std_hac": dict(zip(joints, map(float, std_c_hac / c**2))),
                     "std_block_bootstrap": dict(zip(joints, map(float, std_c_boot / c**2)))},
        settings={"payload_mass": float(payload_mass), "payload_frame": payload_frame,
                  "payload_com": None if payload_com is None else list(map(float, payload_com)),
                  "offset": offset, "align": align, "n_boot": n_boot, "seed": seed},
    )

"""Simulated logs of an arm with no torque sensor: motor currents, a jittery ~100 Hz clock,
and idle segments at the start and the end. Used by docs/arm.md ("Logs of motor currents").

    python examples/current_logged_arm.py OUTDIR [--robot ur5] [--seed 0]

writes OUTDIR/train.csv and OUTDIR/test.csv (two different excitation trajectories of
the same "true" robot) and OUTDIR/gains.json (the drive gains, joint -> K [N·m/A]).

Each CSV has a header ``time, pos_<joint>..., vel_<joint>..., i_<joint>...``:

* time: Unix-epoch seconds, nominal 100 Hz, each stamp off by N(0, (0.15 T)²) and a
  few stamps repeated (as a logger that reads the clock late does);
* pos/vel: the true joint positions and velocities at those instants, plus encoder and
  velocity-estimate noise; no accelerations are logged;
* i: motor currents i = τ / K + noise, τ from Pinocchio's RNEA on a perturbed "true"
  model plus friction, offsets and rotor inertia (:func:`sensorless.simulation.perturbed_truth`);
* the robot rests ``idle_start`` s before and ``idle_end`` s after the motion, which
  blends in and out of a Fourier excitation with a quintic ramp (smooth q, v, v̇).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.simulation import perturbed_truth

#: Drive gains K [N·m/A] per joint (joint side: torque constant × gear ratio), UR5-like.
UR5_GAINS = (10.0, 10.7, 9.6, 4.3, 4.1, 4.0)
T0 = 1_712_345_678.0  # Unix time of the first sample [s]


def _ramp(t: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic smoothstep s(t/T) on [0, T] and its first two time derivatives."""
    x = np.clip(t / T, 0.0, 1.0)
    inside = (t > 0) & (t < T)
    s = x**3 * (10 - 15 * x + 6 * x**2)
    ds = np.where(inside, 30 * x**2 * (1 - x) ** 2 / T, 0.0)
    dds = np.where(inside, 60 * x * (1 - x) * (1 - 2 * x) / T**2, 0.0)
    return s, ds, dds


def truth_model(robot_name: str = "ur5", seed: int = 0):
    """The robot and its 'true' model (seeded), shared by the train and test logs."""
    robot = load_robot(robot_name)
    return robot, perturbed_truth(robot, rng=seed)


def simulate(
    robot, truth, gains, *, seed: int, rate: float = 100.0, motion: float = 20.0, idle_start: float = 2.0,
    idle_end: float = 3.0, ramp: float = 2.0, jitter: float = 0.15, duplicates: int = 3,
    current_noise: float = 0.01, q_noise: float = 1e-4, v_noise: float = 1e-3,
) -> pd.DataFrame:
    """One current-logged run as a table (columns as in the module docstring)."""
    rng = np.random.default_rng(seed)
    fourier = random_fourier(robot, rng=rng, position_fraction=0.3, max_velocity=1.0, max_acceleration=4.0)
    n = int(round((idle_start + motion + idle_end) * rate))
    period = 1.0 / rate
    true_t = np.maximum.accumulate(np.arange(n) * period + rng.normal(0.0, jitter * period, n))  # sampling instants
    stamp = true_t.copy()
    for k in rng.choice(np.arange(1, n), size=duplicates, replace=False):
        stamp[k] = stamp[k - 1]  # the clock was read late: a stamp repeated
    # excitation blended in and out with ramps: q = q_c + w (f - q_c), w = s(τ) s(motion - τ)
    tau_m = true_t - idle_start
    f, fd, fdd = fourier.evaluate(np.clip(tau_m, 0.0, motion))
    s1, d1, dd1 = _ramp(tau_m, ramp)
    s2, d2, dd2 = _ramp(motion - tau_m, ramp)
    w = s1 * s2
    dw = d1 * s2 - s1 * d2
    ddw = dd1 * s2 - 2 * d1 * d2 + s1 * dd2
    qc = fourier.q0
    dev = f - qc
    q = qc + w[:, None] * dev
    v = dw[:, None] * dev + w[:, None] * fd
    a = ddw[:, None] * dev + 2 * dw[:, None] * fd + w[:, None] * fdd
    tau = truth.torques(robot.full_configuration(q), robot.full_velocity(v), robot.full_velocity(a))
    K = np.asarray(gains, dtype=float)
    current = tau / K + rng.normal(0.0, current_noise, tau.shape)
    names = robot.joint_names
    table = {"time": T0 + stamp}
    table.update({f"pos_{j}": q[:, k] + rng.normal(0.0, q_noise, n) for k, j in enumerate(names)})
    table.update({f"vel_{j}": v[:, k] + rng.normal(0.0, v_noise, n) for k, j in enumerate(names)})
    table.update({f"i_{j}": current[:, k] for k, j in enumerate(names)})
    return pd.DataFrame(table)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--robot", default="ur5")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    robot, truth = truth_model(args.robot, args.seed)
    gains = UR5_GAINS[: robot.n_actuated] if robot.n_actuated <= len(UR5_GAINS) else np.full(robot.n_actuated, 8.0)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, seed in (("train", args.seed + 1), ("test", args.seed + 2)):
        simulate(robot, truth, gains, seed=seed).to_csv(args.out / f"{name}.csv", index=False)
    (args.out / "gains.json").write_text(json.dumps(dict(zip(robot.joint_names, map(float, gains))), indent=1))
    print(f"wrote {args.out}/train.csv, test.csv, gains.json ({robot.name}, {robot.n_actuated} joints)")


if __name__ == "__main__":
    main()

"""UR5 logs of joint torques: run1.npz, run2.npz, run3.npz (three excitations), for docs/arm.md §3–5."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    """A perturbed "true" UR5 with friction and armature (:func:`sensorless_studies.simulation.perturbed_truth`)
    on three random Fourier excitations at 100 Hz (10 s each, 30 s with ``full``): ``t, q, v, tau``
    (torques with 1 % of their range as noise, no accelerations) and ``joint_names``."""
    import numpy as np

    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=seed)
    duration = 30.0 if full else 10.0
    names = []
    for k in (1, 2, 3):
        motion = random_fourier(robot, rng=seed + 10 * k).sample(100.0, duration)
        clean = synthetic_trajectory(truth, motion, rng=seed + 10 * k + 1)
        noise = 0.01 * np.ptp(clean.tau, axis=0)
        traj = synthetic_trajectory(truth, motion, noise_std=noise, rng=seed + 10 * k + 1)
        name = f"run{k}.npz"
        np.savez(out / name, t=traj.t, q=traj.q, v=traj.v, tau=traj.tau, joint_names=np.array(robot.joint_names))
        names.append(name)
    return names

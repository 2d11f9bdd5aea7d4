"""A TALOS walking log (walk.npz): sole wrenches with a 30 N sensor bias, torso IMU, no joint torques; README quickstart 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write"]

FEET = ("left_sole_link", "right_sole_link")
IMU_FRAME = "imu_link"  # on the torso


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from sensorless.data import write_npz
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth
    from ..simulation.wrench_log import accelerometer_reading, walking_flags, wrench_log

    rate, duration = 100.0, (20.0 if full else 6.0)
    nominal = load_robot("talos", floating_base=True)
    truth = perturbed_truth(nominal, rng=seed).robot  # masses ±20 %, CoMs ±2 cm off the model file
    n = int(round(duration * rate))
    log = wrench_log(truth, FEET, duration=duration, rate=rate, flags=walking_flags(n, 2, int(0.8 * rate)),
                     bias=np.array([[30.0, 0, 0], [0, 0, 0]]), bias_frame="sole", noise=2.0, seed=seed + 1)
    rng = np.random.default_rng(seed + 2)
    imu = accelerometer_reading(truth, log, IMU_FRAME) + rng.normal(scale=0.03, size=(n, 3))
    write_npz(log.with_(base_a=None, extras={**log.extras, "imu_acc": imu}), out / "walk.npz")
    return ["walk.npz"]

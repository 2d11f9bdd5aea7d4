"""A simulated arm recorded as a ROS 2 bag, then identified from it.

    python examples/ros2_bag_arm.py OUTDIR [--robot ur5]

writes OUTDIR/bag/ (a ROS 2 bag: /joint_states with position, velocity and effort of a
perturbed "true" robot on a Fourier excitation) and runs
``sensorless identify --robot ROBOT --data OUTDIR/bag --out OUTDIR/run`` on it
(result.json, model.urdf patched from the robot's URDF, report.html).
Needs ``pip install sensorless[ros]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from sensorless.cli import app
from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.simulation import perturbed_truth, synthetic_trajectory


def write_bag(traj, path: Path, t0: float = 1.7e9) -> Path:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    JS, Header, Time = (ts.types[k] for k in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header",
                                              "builtin_interfaces/msg/Time"))
    with Writer(path, version=9) as w:
        conn = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        for i, s in enumerate(traj.t):
            ns = int(round((t0 + s) * 1e9))
            msg = JS(header=Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                     name=list(traj.joint_names), position=traj.q[i], velocity=traj.v[i], effort=traj.tau[i])
            w.write(conn, ns, ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--robot", default="ur5")
    a = ap.parse_args()
    robot = load_robot(a.robot)
    truth = perturbed_truth(robot, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(100, 10.0), noise_std=0.05, rng=2)
    a.out.mkdir(parents=True, exist_ok=True)
    bag = write_bag(traj, a.out / "bag")
    app(["identify", "--robot", a.robot, "--data", str(bag), "--out", str(a.out / "run")], standalone_mode=False)


if __name__ == "__main__":
    main()

"""A ROS 2 bag (/joint_states of a simulated UR5 with position, velocity, effort): bag/, for examples/README.md."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write", "write_bag"]


def write_bag(traj, path: Path, t0: float = 1.7e9) -> Path:
    """``traj`` (q, v, τ) as ``sensor_msgs/JointState`` messages on ``/joint_states`` in a ROS 2 bag
    at ``path``, stamped from the Unix time ``t0`` (needs ``sensorless[ros]``: rosbags)."""
    try:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        from sensorless.errors import SensorlessError

        raise SensorlessError("writing a ROS 2 bag needs the rosbags package: pip install 'sensorless[ros]'") from None

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


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    """A perturbed "true" UR5 on a Fourier excitation, 100 Hz for 10 s (30 s with ``full``),
    torques with 0.05 N·m noise."""
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=seed)
    motion = random_fourier(robot, rng=seed + 1).sample(100, 30.0 if full else 10.0)
    write_bag(synthetic_trajectory(truth, motion, noise_std=0.05, rng=seed + 2), Path(out) / "bag")
    return ["bag/"]

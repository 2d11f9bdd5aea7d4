"""ROS 1 / ROS 2 bags and MCAP into a Trajectory: bags written here with rosbags' own writers."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from sensorless.data import read_trajectory  # noqa: E402
from sensorless.data.rosbag import read_rosbag  # noqa: E402
from sensorless.errors import DataError, JointNameError  # noqa: E402

T0 = 1_700_000_000.0  # a realistic epoch stamp: t must come out relative to it
JOINTS = ["j1", "j2", "j3"]


def _signals(n=200, rate=100.0):
    t = np.arange(n) / rate
    q = np.column_stack([0.3 * np.sin(2 * np.pi * f * t) for f in (0.5, 0.7, 0.9)])
    v = np.gradient(q, t, axis=0)
    tau = np.column_stack([np.cos(2 * np.pi * f * t) for f in (0.5, 0.7, 0.9)])
    return t, q, v, tau


def _time(ts, s):
    sec = int(np.floor(s))
    return ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((s - sec) * 1e9)))


def _header(ts, s, frame=""):
    return ts.types["std_msgs/msg/Header"](stamp=_time(ts, s), frame_id=frame)


def _vec3(ts, x):
    return ts.types["geometry_msgs/msg/Vector3"](x=float(x[0]), y=float(x[1]), z=float(x[2]))


def _messages(ts, bag_names=None, with_velocity=True):
    """(topic, stamp_s, msg) for joint states (shuffled order + an extra joint), an IMU at 2/3 the
    rate, offset in time, and one wrench topic at a different rate."""
    t, q, v, tau = _signals()
    names = bag_names or JOINTS
    JS, Imu, W = (ts.types[k] for k in ("sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu",
                                        "geometry_msgs/msg/WrenchStamped"))
    order = [2, 0, 1]  # the bag lists joints in another order, plus a gripper joint
    out = []
    for i, s in enumerate(t):
        out.append(("/joint_states", T0 + s, JS(
            header=_header(ts, T0 + s), name=[names[k] for k in order] + ["gripper"],
            position=np.r_[q[i, order], 0.01], velocity=np.r_[v[i, order], 0.0] if with_velocity else np.zeros(0),
            effort=np.r_[tau[i, order], 0.0])))
    ti = np.arange(-0.05, t[-1] + 0.06, 1 / 66.0)  # IMU covers the joint samples, other clock
    for s in ti:
        acc = np.array([1.0 + s, 2.0 * s, 9.81])  # linear in time: interpolation is exact
        quat = ts.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=np.sin(0.1 * s), w=np.cos(0.1 * s))
        out.append(("/imu", T0 + s, Imu(header=_header(ts, T0 + s, "imu_link"), orientation=quat,
                                         orientation_covariance=np.zeros(9), angular_velocity=_vec3(ts, [0, 0, 0.2]),
                                         angular_velocity_covariance=np.zeros(9), linear_acceleration=_vec3(ts, acc),
                                         linear_acceleration_covariance=np.zeros(9))))
    tw = np.arange(-0.02, t[-1] + 0.03, 1 / 250.0)
    for s in tw:
        w = ts.types["geometry_msgs/msg/Wrench"](force=_vec3(ts, [s, -s, 5.0]), torque=_vec3(ts, [0, 0.5 * s, 0]))
        out.append(("/ft", T0 + s, W(header=_header(ts, T0 + s, "ft_sensor"), wrench=w)))
    return sorted(out, key=lambda x: x[1])


def write_ros2(path, storage=StoragePlugin.SQLITE3, **kw):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = {"/joint_states": "sensor_msgs/msg/JointState", "/imu": "sensor_msgs/msg/Imu",
             "/ft": "geometry_msgs/msg/WrenchStamped"}
    with Writer2(path, version=9, storage_plugin=storage) as w:
        conns = {tp: w.add_connection(tp, ty, typestore=ts) for tp, ty in types.items()}
        for topic, s, msg in _messages(ts, **kw):
            w.write(conns[topic], int(s * 1e9), ts.serialize_cdr(msg, types[topic]))
    return path


def write_ros1(path):
    ts = get_typestore(Stores.ROS1_NOETIC)
    types = {"/joint_states": "sensor_msgs/msg/JointState", "/imu": "sensor_msgs/msg/Imu",
             "/ft": "geometry_msgs/msg/WrenchStamped"}
    with Writer1(path) as w:
        conns = {tp: w.add_connection(tp, ty, typestore=ts) for tp, ty in types.items()}
        for topic, s, msg in _messages(_ros1_compat(ts)):
            w.write(conns[topic], int(s * 1e9), ts.serialize_ros1(msg, types[topic]))
    return path


def _ros1_compat(ts):
    """ROS 1 headers carry a seq and Time has the same fields in rosbags; wrap Header to add seq."""
    Header = ts.types["std_msgs/msg/Header"]

    class _TS:
        types = dict(ts.types)

    _TS.types["std_msgs/msg/Header"] = lambda stamp, frame_id: Header(seq=0, stamp=stamp, frame_id=frame_id)
    return _TS


def _check(traj):
    t, q, v, tau = _signals()
    assert traj.joint_names == tuple(JOINTS)
    np.testing.assert_allclose(traj.t, t, atol=2e-6)  # relative to the first stamp
    assert traj.provenance["t0_unix"] == pytest.approx(T0, abs=1e-6)
    np.testing.assert_allclose(traj.q, q, atol=1e-12)
    np.testing.assert_allclose(traj.v, v, atol=1e-12)
    np.testing.assert_allclose(traj.tau, tau, atol=1e-12)
    acc = traj.extras["imu_acc"]
    np.testing.assert_allclose(acc, np.column_stack([1.0 + t, 2.0 * t, np.full_like(t, 9.81)]), atol=1e-5)
    np.testing.assert_allclose(traj.extras["imu_quat"][:, 2], np.sin(0.1 * t), atol=1e-5)
    w = traj.extras["wrench"]
    assert w.shape == (len(t), 1, 6)
    np.testing.assert_allclose(w[:, 0, 0], t, atol=1e-5)
    np.testing.assert_allclose(w[:, 0, 4], 0.5 * t, atol=1e-5)
    assert traj.provenance["wrench_frames"] == ["ft_sensor"] and traj.provenance["imu_frame_id"] == "imu_link"


def test_ros2_bag_round_trip(tmp_path):
    bag = write_ros2(tmp_path / "run")
    _check(read_rosbag(bag, wrench_topics=["/ft"], joint_names=JOINTS))


def test_ros2_mcap_round_trip_through_read_trajectory(tmp_path):
    bag = write_ros2(tmp_path / "run", storage=StoragePlugin.MCAP)
    mcap = next(bag.glob("*.mcap"))
    for p in (bag, mcap):  # the bag directory and the bare .mcap file
        _check(read_trajectory(p, joint_names=JOINTS, columns={"joint_states": "/joint_states", "wrench": ["/ft"]}))


def test_ros1_bag_round_trip(tmp_path):
    _check(read_rosbag(write_ros1(tmp_path / "run.bag"), wrench_topics="all", joint_names=JOINTS))


def test_joint_map_and_robot_order(tmp_path):
    bag = write_ros2(tmp_path / "run", bag_names=["a", "b", "c"])
    traj = read_rosbag(bag, joint_map={"a": "j1", "b": "j2", "c": "j3"}, joint_names=["j3", "j1"])
    t, q, _, _ = _signals()
    assert traj.joint_names == ("j3", "j1")
    np.testing.assert_allclose(traj.q, q[:, [2, 0]], atol=1e-12)
    traj = read_trajectory(bag, columns={"joints": "a:j1,b:j2,c:j3"})
    assert traj.joint_names == ("j3", "j1", "j2", "gripper")  # the first message's order, renamed


def test_errors_name_the_topic(tmp_path):
    bag = write_ros2(tmp_path / "run")
    with pytest.raises(JointNameError, match=r"topic '/joint_states' message 0 .* but not \['elbow'\]"):
        read_rosbag(bag, joint_names=["j1", "elbow"])
    with pytest.raises(DataError, match=r"no topic '/arm/joint_states' \(joint states\).*/joint_states \[sensor_msgs"):
        read_rosbag(bag, joint_states_topic="/arm/joint_states")
    with pytest.raises(DataError, match=r"topic '/imu' \(wrench\) has type sensor_msgs/msg/Imu"):
        read_rosbag(bag, wrench_topics=["/imu"])
    with pytest.raises(DataError, match=r"unknown key\(s\) \['q'\] in columns for a ROS bag"):
        read_trajectory(bag, columns={"q": "0:3"})
    (tmp_path / "bad.bag").write_bytes(b"not a bag at all")
    with pytest.raises(DataError, match="bad.bag: not a readable ROS bag"):
        read_trajectory(tmp_path / "bad.bag")


def test_empty_velocity_is_dropped(tmp_path):
    traj = read_rosbag(write_ros2(tmp_path / "run", with_velocity=False), joint_names=JOINTS)
    assert traj.v is None and traj.tau is not None


def test_cli_identify_reads_a_bag(tmp_path):
    """`identify --data BAG_DIR` on a simulated UR5 log written as a ROS 2 bag: the model fits it."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(100, 8.0), noise_std=0.05, rng=2)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    JS = ts.types["sensor_msgs/msg/JointState"]
    bag = tmp_path / "bag"
    with Writer2(bag, version=9) as w:
        c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        for i, s in enumerate(traj.t):
            msg = JS(header=_header(ts, T0 + s), name=list(traj.joint_names), position=traj.q[i],
                     velocity=traj.v[i], effort=traj.tau[i])
            w.write(c, int((T0 + s) * 1e9), ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    out = tmp_path / "o"
    res = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(bag), "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "result.json").read_text())
    page = (out / "report.html").read_text()  # the run's one-page report: metrics, plot, consistency, settings
    for needle in ("shoulder_pan_joint", "data:image/png;base64,", "Physical consistency", "Identifiability", str(bag)):
        assert needle in page, needle
    assert doc["train_metrics"]["n_samples"] == len(traj) and doc["train_metrics"]["mean_nrmse"] < 0.05
    bad = CliRunner().invoke(app, ["identify", "--robot", "panda", "--data", str(bag), "--out", str(tmp_path / "p")])
    assert bad.exit_code == 2 and "/joint_states" in bad.output and not (tmp_path / "p").exists()

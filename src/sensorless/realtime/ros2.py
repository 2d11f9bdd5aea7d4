"""``sensorless stream --input ros2:/joint_states``: the streamed monitor as a ROS 2 node (needs ``rclpy``).

Subscribes to ``sensor_msgs/msg/JointState`` (position, velocity, effort, by joint name: any
order, extra joints ignored) and publishes, per message, on ``OUT/external_torque``
(``std_msgs/msg/Float64MultiArray``, the monitored joints in the layout's dimension label),
``OUT/force`` (``geometry_msgs/msg/Vector3Stamped`` in the frame, with ``--frame``) and
``OUT/contact`` (``std_msgs/msg/Bool``), OUT the ``--output ros2:PREFIX`` (default
``/sensorless``). ROS 2 headers carry no sequence number: a gap in the stamps longer than 1.5
sample periods counts the missing samples as dropped. The mapping functions below need no ROS.
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError, OptionError, setting

__all__ = ["joint_state_sample", "stamp_seconds", "stamp_gap", "run_ros2"]


def stamp_seconds(sec: int, nanosec: int) -> float:
    """A ``builtin_interfaces/Time`` as seconds."""
    return float(sec) + 1e-9 * float(nanosec)


def stamp_gap(t: float, last: float | None, dt: float) -> int:
    """Samples missing between two stamps ``dt`` apart (0 for consecutive samples)."""
    return 0 if last is None else max(int(round((t - last) / dt)) - 1, 0)


def joint_state_sample(layout, names, position, velocity, effort, index: int = 0) -> tuple[np.ndarray, np.ndarray,
                                                                                             np.ndarray]:
    """(q, v, τ) in the record's joint order from a JointState's fields; DataError naming the message
    ``index`` and the joint or field that is missing or not finite."""
    names = list(names)
    where = {n: i for i, n in enumerate(names)}
    missing = [j for j in layout.joints if j not in where]
    if missing:
        raise DataError(f"JointState message {index}: no joint(s) {missing} (it names {names})")
    for field, vals in (("position", position), ("velocity", velocity), ("effort", effort)):
        if len(vals) != len(names):
            raise DataError(f"JointState message {index}: {len(vals)} {field} values for {len(names)} names")
    iq = [where[j] for j in layout.joints]
    q = np.asarray(position, float)[iq]
    v = np.asarray(velocity, float)[iq]
    tau = np.asarray(effort, float)[[where[j] for j in layout.actuated]]
    for field, vals, joints in (("position", q, layout.joints), ("velocity", v, layout.joints),
                                ("effort", tau, layout.actuated)):
        bad = np.flatnonzero(~np.isfinite(vals))
        if bad.size:
            raise DataError(f"JointState message {index}: {field} of {joints[bad[0]]} is {vals[bad[0]]}")
    return q, v, tau


def run_ros2(monitor, topic: str, prefix: str, skip_bad: bool = False):  # pragma: no cover - needs ROS 2
    """Spin a node until shutdown (SIGINT/SIGTERM); returns the :class:`~.transport.StreamStats`."""
    try:
        import rclpy
        from geometry_msgs.msg import Vector3Stamped
        from rclpy.executors import ExternalShutdownException
        from rclpy.node import Node
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Bool, Float64MultiArray, MultiArrayDimension
    except ImportError as e:
        raise OptionError(f"{setting('input', f'ros2:{topic}')} needs a ROS 2 installation with rclpy (source /opt/ros/DISTRO/setup.bash "
                          f"first); {e}") from None
    import time

    from .transport import StreamStats

    layout, dt = monitor.layout, monitor.th.dt
    stats = StreamStats()
    state = {"last": None, "index": 0}
    rclpy.init()
    node = Node("sensorless_stream")
    pub_tau = node.create_publisher(Float64MultiArray, f"{prefix}/external_torque", 10)
    pub_f = node.create_publisher(Vector3Stamped, f"{prefix}/force", 10) if monitor.frame else None
    pub_c = node.create_publisher(Bool, f"{prefix}/contact", 10)
    dim = MultiArrayDimension(label=",".join(layout.monitored), size=len(layout.monitored), stride=len(layout.monitored))
    m = len(layout.monitored)

    def on_joint_state(msg) -> None:
        t_in = time.perf_counter()
        state["index"] += 1
        t = stamp_seconds(msg.header.stamp.sec, msg.header.stamp.nanosec)
        try:
            q, v, tau = joint_state_sample(layout, msg.name, msg.position, msg.velocity, msg.effort, state["index"])
        except DataError:
            if not skip_bad:
                raise
            stats.bad += 1
            return
        stats.dropped += stamp_gap(t, state["last"], dt)
        state["last"] = t
        out = monitor.step(state["index"], t, q, v, tau)
        arr = Float64MultiArray()
        arr.layout.dim = [dim]
        arr.data = [float(x) for x in out[2 : 2 + m]]
        pub_tau.publish(arr)
        if pub_f is not None:
            f = Vector3Stamped()
            f.header.stamp, f.header.frame_id = msg.header.stamp, monitor.frame
            f.vector.x, f.vector.y, f.vector.z = (float(x) for x in out[2 + m : 5 + m])
            pub_f.publish(f)
        pub_c.publish(Bool(data=bool(out[-1])))
        stats.samples += 1
        stats.latency.add(time.perf_counter() - t_in)

    node.create_subscription(JointState, topic, on_joint_state, 100)
    try:
        rclpy.spin(node)
        stats.stopped_by = "shutdown"
    except KeyboardInterrupt:
        stats.stopped_by = "SIGINT"
    except ExternalShutdownException:  # SIGTERM: rclpy shuts the context down
        stats.stopped_by = "SIGTERM"
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    stats.contact_samples = monitor.contact_samples
    stats.out_of_range = monitor.rejected
    return stats

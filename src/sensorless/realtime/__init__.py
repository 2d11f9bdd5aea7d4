"""Real-time estimation: the collision monitor one sample at a time (``sensorless stream``).

:mod:`.monitor` does the per-sample work (momentum observer step, rest and static-band
decisions, force at a frame, contact flag), :mod:`.records` defines the CSV and binary sample
records, :mod:`.transport` the endpoints (stdin/stdout, UDP on the loopback) and the loop,
:mod:`.ros2` the ROS 2 node (with ``rclpy``).
"""

from .monitor import StreamMonitor, StreamThresholds
from .records import FORMATS, RecordLayout
from .transport import LatencyHistogram, parse_endpoint, run_stream

__all__ = ["FORMATS", "LatencyHistogram", "RecordLayout", "StreamMonitor", "StreamThresholds",
           "parse_endpoint", "run_stream"]

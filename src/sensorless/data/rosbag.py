"""ROS 1 / ROS 2 bags and MCAP files into a :class:`Trajectory` (with the ``rosbags`` package).

Accepted: a ROS 1 ``.bag``, a ROS 2 bag directory (``metadata.yaml`` + ``.db3``/``.mcap``),
or a bare ``.mcap`` / ``.db3`` file. Topics:

* ``sensor_msgs/JointState`` (required): ``position → q``, ``velocity → v``, ``effort → tau``.
  A velocity/effort field that some used message leaves empty is dropped (DataWarning).
  Messages may list joints in any order and carry more joints than wanted (a gripper);
  messages with none of the wanted joints (another publisher on the topic) are skipped.
* ``sensor_msgs/Imu`` (optional): ``linear_acceleration → extras["imu_acc"]`` (N, 3),
  ``angular_velocity → extras["imu_gyro"]`` (N, 3), ``orientation → extras["imu_quat"]``
  (N, 4, ``[x y z w]``), all in the IMU message's frame.
* ``geometry_msgs/WrenchStamped`` (optional, several): ``extras["wrench"]`` (N, n_topics, 6)
  ``[f; τ]`` in each message's header frame (frame ids in ``provenance["wrench_frames"]``).
  Pass ``wrench_key="contact_forces"`` when they are already world-axis contact wrenches.

Time: the JointState header stamps (the bag's receive time when a stamp is zero) define the
samples; ``t`` starts at 0 and the first stamp is kept as ``provenance["t0_unix"]`` [s].
IMU and wrench streams are aligned to those samples by linear interpolation on their own
stamps (orientation by spherical interpolation, ``scipy.spatial.transform.Slerp``). Joint
samples outside a stream's time span are dropped (DataWarning); a stream gap longer than
``max_gap`` × its median period under a joint sample is a :class:`~sensorless.errors.DataError`.

Joint names: ``joint_map`` renames bag names to model names (``{"shoulder": "joint1"}``);
the joints read are ``joint_names``, else ``robot.joint_names``, else those of the first
message. A wanted joint the topic never publishes is a :class:`~sensorless.errors.JointNameError`
naming the topic. From the command line, ``--columns`` carries the topics for a bag:
``'joint_states=/arm/joint_states;imu=/imu/data;wrench=/ft_left|/ft_right;joints=bag_a:j1|bag_b:j2'``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from ..errors import DataError, DataWarning, JointNameError, setting
from .imu import IMU_KEY
from .trajectory import Trajectory
from .validation import validate_trajectory

if TYPE_CHECKING:
    from ..robot import Robot

__all__ = ["read_rosbag", "is_rosbag", "rosbag_options", "ROSBAG_SUFFIXES", "JOINT_STATE", "IMU", "WRENCH"]

ROSBAG_SUFFIXES = (".bag", ".mcap", ".db3")
JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
WRENCH = "geometry_msgs/msg/WrenchStamped"
#: ``columns`` keys that carry topics for a bag (see :func:`rosbag_options`).
TOPIC_KEYS = ("joint_states", "imu", "wrench", "joints")


def is_rosbag(path: str | Path) -> bool:
    """True for a ``.bag``/``.mcap``/``.db3`` path or a directory holding ``metadata.yaml``."""
    p = Path(path)
    return p.suffix.lower() in ROSBAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())


def rosbag_options(columns: Mapping[str, Any] | None, src: str) -> dict[str, Any]:
    """:func:`read_rosbag` keyword arguments from a ``columns`` map (the CLI's ``--columns``).

    Keys: ``joint_states`` (topic), ``imu`` (topic), ``wrench`` (topic or list), ``joints``
    (``bag_name:model_name`` items, a list or one ``,``-separated string)."""
    if not columns:
        return {}
    unknown = [k for k in columns if k not in TOPIC_KEYS]
    if unknown:
        raise DataError(f"unknown key(s) {unknown} in columns for a ROS bag; valid keys: {list(TOPIC_KEYS)} "
                        "(e.g. 'joint_states=/arm/joint_states;imu=/imu;wrench=/ft')", src)
    out: dict[str, Any] = {}
    if "joint_states" in columns:
        out["joint_states_topic"] = str(columns["joint_states"])
    if "imu" in columns:
        out["imu_topic"] = str(columns["imu"])
    if "wrench" in columns:
        w = columns["wrench"]
        out["wrench_topics"] = [w] if isinstance(w, str) else list(w)
    if "joints" in columns:
        items = columns["joints"]
        items = items.split(",") if isinstance(items, str) else list(items)
        pairs = {}
        for item in items:
            if ":" not in str(item):
                raise DataError(f"joints entry {item!r} is not BAG_NAME:MODEL_NAME", src)
            a, b = (s.strip() for s in str(item).split(":", 1))
            pairs[a] = b
        out["joint_map"] = pairs
    return out


def read_rosbag(
    path: str | Path,
    *,
    joint_states_topic: str | None = None,
    imu_topic: str | None = None,
    wrench_topics: Sequence[str] | None = None,
    joint_map: Mapping[str, str] | None = None,
    joint_names: Sequence[str] | None = None,
    robot: "Robot | None" = None,
    wrench_key: str = "wrench",
    max_gap: float = 4.0,
    allow_duplicate_times: bool = False,
    outliers: str = "error",
    trim=None,
    skip_bad_rows: bool = False,
) -> Trajectory:
    """Read a ROS bag / MCAP file into a validated Trajectory (see the module docstring).
    ``trim`` and ``skip_bad_rows``: :func:`~sensorless.data.validate_trajectory`.

    ``joint_states_topic`` defaults to the bag's only JointState topic; ``imu_topic`` to its
    only Imu topic (none if there are zero or several); ``wrench_topics`` to none (give the
    topics, or ``"all"`` for every WrenchStamped topic, sorted).
    """
    path = Path(path)
    src = str(path)
    if not path.exists():
        raise DataError("no such file or bag directory", src)
    streams = _read_streams(path, src, joint_states_topic, imu_topic, wrench_topics)
    js_topic, js = streams.pop("joint_states")
    wanted_from_map = dict(joint_map or {})
    rename = lambda n: wanted_from_map.get(n, n)  # noqa: E731
    if joint_names is not None:
        wanted = list(joint_names)
    elif robot is not None:
        wanted = list(robot.joint_names)
    else:
        wanted = [rename(n) for n in js[0][1].name]
    t, q, v, tau, skipped = _joint_arrays(js, wanted, rename, js_topic, src)
    extras: dict[str, np.ndarray] = {}
    prov: dict[str, Any] = {"rosbag": {"joint_states": js_topic}}
    keep = np.ones(len(t), dtype=bool)
    aligned: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    for kind, (topic, msgs) in streams.items():
        ts = np.array([stamp for stamp, _ in msgs])
        inside = (t >= ts[0]) & (t <= ts[-1])
        if not inside.any():
            raise DataError(f"topic '{topic}' ({ts[0]:.3f}..{ts[-1]:.3f} s) does not overlap the joint states of "
                            f"'{js_topic}' ({t[0]:.3f}..{t[-1]:.3f} s)", src)
        keep &= inside
        aligned[kind] = (ts, msgs, topic)
    if not keep.all():
        warnings.warn(f"{src}: {int((~keep).sum())} joint-state sample(s) outside the IMU/wrench streams' time "
                      "span were dropped", DataWarning, stacklevel=2)
    t, q = t[keep], q[keep]
    v = None if v is None else v[keep]
    tau = None if tau is None else tau[keep]
    for kind, (ts, msgs, topic) in aligned.items():
        _check_gaps(ts, t, max_gap, topic, src)
        if kind == "imu":
            prov["rosbag"]["imu"] = topic
            acc = np.array([_xyz(m.linear_acceleration) for _, m in msgs])
            gyro = np.array([_xyz(m.angular_velocity) for _, m in msgs])
            quat = np.array([[m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w] for _, m in msgs])
            extras[IMU_KEY] = _interp(ts, acc, t)
            extras["imu_gyro"] = _interp(ts, gyro, t)
            if np.all(np.linalg.norm(quat, axis=1) > 0.5):  # ROS: all zeros = no orientation estimate
                extras["imu_quat"] = _slerp(ts, quat, t)
            prov["imu_frame_id"] = msgs[0][1].header.frame_id
        else:
            prov["rosbag"].setdefault("wrench", []).append(topic)
            w = np.array([[*_xyz(m.wrench.force), *_xyz(m.wrench.torque)] for _, m in msgs])
            extras.setdefault("_w", []).append(_interp(ts, w, t))
            prov.setdefault("wrench_frames", []).append(msgs[0][1].header.frame_id)
    if "_w" in extras:
        extras[wrench_key] = np.stack(extras.pop("_w"), axis=1)
    t0 = float(t[0])
    prov.update({"t0_unix": t0, "q": "logged", **({"v": "logged"} if v is not None else {})})
    if skipped:
        prov["rosbag"]["skipped_messages"] = skipped
    traj = Trajectory(t=t - t0, q=q, joint_names=tuple(wanted), v=v, tau=tau, extras=extras,
                      units={"t": "s (from the JointState header stamps, relative to provenance t0_unix)"},
                      source=src, provenance=prov)
    return validate_trajectory(traj, robot, allow_duplicate_times=allow_duplicate_times, outliers=outliers, trim=trim,
                               skip_bad_rows=skip_bad_rows)


# ---- reading --------------------------------------------------------------------------
def _stamp(msg: Any, receive_ns: int) -> float:
    st = msg.header.stamp
    s = float(st.sec) + 1e-9 * float(st.nanosec)
    return s if s > 0 else 1e-9 * receive_ns


def _xyz(vec: Any) -> tuple[float, float, float]:
    return (vec.x, vec.y, vec.z)


def _pick(topics: dict[str, str], msgtype: str, given: str | None, what: str, src: str, required: bool) -> str | None:
    of_type = sorted(t for t, ty in topics.items() if ty == msgtype)
    if given is not None:
        if given not in topics:
            raise DataError(f"no topic '{given}' ({what}) in the bag; topics: {_listing(topics)}", src)
        if topics[given] != msgtype:
            raise DataError(f"topic '{given}' ({what}) has type {topics[given]}, expected {msgtype}", src)
        return given
    if len(of_type) == 1:
        return of_type[0]
    if required:
        if not of_type:
            raise DataError(f"no {msgtype} topic in the bag; topics: {_listing(topics)}", src)
        raise DataError(f"several {msgtype} topics {of_type}; choose one ({setting('columns', {'joint_states': 'TOPIC'})})",
                        src)
    return None


def _listing(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} [{ty}]" for t, ty in sorted(topics.items())) or "(none)"


def _read_streams(path: Path, src: str, js_topic, imu_topic, wrench_topics) -> dict[str, tuple[str, list]]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        with reader:
            topics = {c.topic: c.msgtype for c in reader.connections}
            js_topic = _pick(topics, JOINT_STATE, js_topic, "joint states", src, required=True)
            imu_topic = _pick(topics, IMU, imu_topic, "IMU", src, required=False)
            if wrench_topics == "all":
                wrench_topics = sorted(t for t, ty in topics.items() if ty == WRENCH)
            wrench_topics = [_pick(topics, WRENCH, w, "wrench", src, True) for w in (wrench_topics or [])]
            wanted = {js_topic: "joint_states"}
            if imu_topic:
                wanted[imu_topic] = "imu"
            for k, w in enumerate(wrench_topics):
                wanted[w] = f"wrench{k}"
            got: dict[str, list] = {w: [] for w in wanted}
            conns = [c for c in reader.connections if c.topic in wanted]
            for conn, ns, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                got[conn.topic].append((_stamp(msg, ns), msg))
            _check_counts(reader, conns, got, src)
    except DataError:
        raise
    except Exception as exc:  # rosbags raises its own ReaderError/AnyReaderError/SerdeError, sqlite/OS errors
        text = " ".join(str(exc).split())[:300]
        raise DataError(f"not a readable ROS bag / MCAP file ({type(exc).__name__}: {text})", src) from None
    out = {}
    for topic, kind in wanted.items():
        msgs = sorted(got[topic], key=lambda x: x[0])
        if not msgs:
            raise DataError(f"topic '{topic}' has no messages", src)
        out[kind] = (topic, msgs)
    return out


def _joint_arrays(msgs: list, wanted: list[str], rename, topic: str, src: str):
    """(t, q, v|None, tau|None, n_skipped) from JointState messages, columns in ``wanted`` order."""
    seen: set[str] = set()
    rows_t, rows = [], {"position": [], "velocity": [], "effort": []}
    skipped = 0
    cache: dict[tuple, np.ndarray | None] = {}
    for k, (stamp, m) in enumerate(msgs):
        names = tuple(m.name)
        if names not in cache:
            model_names = [rename(n) for n in names]
            seen.update(model_names)
            have = [w for w in wanted if w in model_names]
            if not have:
                cache[names] = None
            elif len(have) < len(wanted):
                missing = [w for w in wanted if w not in model_names]
                raise JointNameError(f"topic '{topic}' message {k} (t = {stamp:.6f} s) has joints {list(names)} but "
                                     f"not {missing}; map bag names: {setting('columns', {'joints': 'BAG:MODEL'})}", src)
            else:
                cache[names] = np.array([model_names.index(w) for w in wanted])
        idx = cache[names]
        if idx is None:
            skipped += 1
            continue
        rows_t.append(stamp)
        for field in rows:
            vals = np.asarray(getattr(m, field), dtype=float)
            rows[field].append(vals[idx] if vals.size == len(names) else None)
    if not rows_t:
        raise JointNameError(f"topic '{topic}' never publishes the joints {wanted}; it has {sorted(seen)} "
                             f"(map names: {setting('columns', {'joints': 'BAG:MODEL'})})", src)
    out = {}
    for field, vals in rows.items():
        if all(r is not None for r in vals):
            out[field] = np.array(vals)
        elif field != "position" and any(r is not None for r in vals):
            warnings.warn(f"{src}: topic '{topic}' leaves '{field}' empty in some messages; it is not used",
                          DataWarning, stacklevel=3)
        elif field == "position":
            k = next(i for i, r in enumerate(vals) if r is None)
            raise DataError(f"topic '{topic}' message {k} has no position for every joint", src)
    return np.array(rows_t), out["position"], out.get("velocity"), out.get("effort"), skipped


def _interp(ts: np.ndarray, vals: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, ts, vals[:, c]) for c in range(vals.shape[1])])


def _slerp(ts: np.ndarray, quat: np.ndarray, t: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation, Slerp

    ts, first = np.unique(ts, return_index=True)
    if len(ts) == 1:
        return np.repeat(quat[first][:1] / np.linalg.norm(quat[first][0]), len(t), axis=0)
    return Slerp(ts, Rotation.from_quat(quat[first]))(t).as_quat()


def _check_gaps(ts: np.ndarray, t: np.ndarray, max_gap: float, topic: str, src: str) -> None:
    """DataError if a joint sample falls in a gap of the stream longer than ``max_gap`` periods."""
    if len(ts) < 2:
        return
    steps = np.diff(ts)
    period = float(np.median(steps))
    big = np.flatnonzero(steps > max_gap * max(period, 1e-12))
    for g in big:
        if np.any((t > ts[g]) & (t < ts[g + 1])):
            raise DataError(f"topic '{topic}' has a {steps[g]:.4g} s gap ({steps[g] / period:.0f} periods) at "
                            f"{ts[g] - ts[0]:.4f} s into the stream; joint samples there cannot be aligned", src)


def _bad_chunks(reader) -> list[int]:
    """Byte offsets of MCAP chunks whose record does not start with the chunk opcode (zeroed or
    overwritten); best effort through rosbags' reader internals, [] when they are not there."""
    bad = []
    for r in getattr(reader, "readers", []):
        for st in getattr(r, "storages", None) or [getattr(r, "storage", None)]:
            bio = getattr(st, "bio", None)
            for chunk in (getattr(st, "chunks", None) or []) if bio is not None else []:
                bio.seek(chunk.chunk_start_offset)
                if bio.read(1) != b"\x06":
                    bad.append(int(chunk.chunk_start_offset))
    return bad


def _check_counts(reader, conns, got: dict, src: str) -> None:
    """DataError when a topic yields fewer messages than the bag's index/statistics declare (a corrupt
    chunk that the reader skips without a word); with ``skip_bad`` a DataWarning counting them."""
    from .limits import current_options

    declared: dict[str, int] = {}
    for c in conns:
        declared[c.topic] = declared.get(c.topic, 0) + int(getattr(c, "msgcount", 0) or 0)
    lost = {t: n - len(got[t]) for t, n in declared.items() if n > len(got[t])}
    if not lost:
        return
    chunks = _bad_chunks(reader)
    where = (f"corrupt chunk(s) at byte offset(s) {', '.join(map(str, chunks[:5]))}" if chunks
             else "unreadable data")
    counts = "; ".join(f"'{t}': {k} of {declared[t]} messages lost" for t, k in sorted(lost.items()))
    if current_options().get("skip_bad"):
        warnings.warn(f"{src}: {setting('skip_bad', True)}: skipped {len(chunks) or 'some'} {where} ({counts})", DataWarning,
                      stacklevel=3)
        return
    raise DataError(f"{where} ({counts}); read the rest with {setting('skip_bad', True)}", src)

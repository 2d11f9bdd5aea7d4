"""Class ``containers``: corrupt ROS 2 MCAP bags and CSV logs with bad time stamps.

* MCAP: a clean bag of 400 ``JointState`` messages (small chunks), written once per worker with
  rosbags, then per case a zeroed or partly zeroed chunk, a truncation or flipped bytes; read with
  ``read_trajectory``. ``garbage``: success with fewer samples than written and no warning.
* CSV (the worker's simulated log): every stamp duplicated (every row twice, or two samples per
  stamp), time going backwards, a short final row, a few duplicated stamps; run through
  ``sensorless predict`` (CliRunner). ``garbage``: exit 0 with every stamp duplicated and no
  warning, or with a sample count other than the distinct stamps written and no warning.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .common import cli, cli_outcome, one_line, setup_model, warned

N_MSG = 400


def _write_mcap(path: Path) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2 import storage_mcap as sm
    from rosbags.typesys import Stores, get_typestore

    original = sm.McapWriter.write

    def small_chunks(self, *a, **kw):  # chunks of ~4 kB (other writers use small chunks too)
        original(self, *a, **kw)
        if self.chunk.bio.tell() > 4096:
            self.close_chunk()

    ts = get_typestore(Stores.ROS2_HUMBLE)
    js, hdr, tm = (ts.types[k] for k in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header",
                                         "builtin_interfaces/msg/Time"))
    sm.McapWriter.write = small_chunks
    try:
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
            for i in range(N_MSG):
                s = 1_700_000_000 + i / 100.0
                t = tm(sec=int(s), nanosec=int(round((s - int(s)) * 1e9)))
                q = [0.3 * np.sin(0.5 * i / 100.0), 0.2 * np.cos(0.7 * i / 100.0)]
                msg = js(header=hdr(stamp=t, frame_id=""), name=["j1", "j2"], position=np.array(q),
                         velocity=np.zeros(2), effort=np.array([1.0 + q[0], 0.5 - q[1]]))
                w.write(c, int(s * 1e9), ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    finally:
        sm.McapWriter.write = original
    return next(path.glob("*.mcap"))


def chunks(data: bytes) -> list[tuple[int, int]]:
    """(offset of the body, body length) of every Chunk record (opcode 0x06) of an MCAP file."""
    out, i = [], 8
    while i + 9 <= len(data):
        op, n = data[i], struct.unpack_from("<Q", data, i + 1)[0]
        if op == 0x06:
            out.append((i + 9, n))
        if op == 0x0F or n > len(data):  # footer
            break
        i += 9 + n
    return out


def setup(d: Path, scale: float) -> dict:
    ctx = setup_model(d)
    ctx["mcap"] = _write_mcap(d / "bag")
    ctx["mcap_bytes"] = ctx["mcap"].read_bytes()
    ctx["chunks"] = chunks(ctx["mcap_bytes"])
    return ctx


def mcap_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.data import read_trajectory
    from sensorless.errors import SensorlessError
    import warnings

    data = bytearray(ctx["mcap_bytes"])
    kind = str(rng.choice(["zero_records", "zero_records", "zero_chunk", "zero_part", "truncate", "flip"]))
    off, n = ctx["chunks"][int(rng.integers(len(ctx["chunks"])))]
    if kind == "zero_records":  # the chunk's records zeroed, its header (lengths) intact and its CRC cleared
        clen = struct.unpack_from("<I", data, off + 28)[0]
        rec = off + 32 + clen + 8
        data[off + 24:off + 28] = bytes(4)
        data[rec:off + n] = bytes(off + n - rec)
    elif kind == "zero_chunk":
        data[off:off + n] = bytes(n)
    elif kind == "zero_part":
        a = off + int(rng.integers(0, n))
        data[a:a + int(rng.integers(1, n))] = bytes(len(data[a:a + int(rng.integers(1, n))]))
    elif kind == "truncate":
        data = data[: int(rng.integers(8, len(data)))]
    else:
        for k in rng.integers(0, len(data), size=int(rng.integers(1, 20))):
            data[int(k)] = int(rng.integers(0, 256))
    f = d / "case" / "bad.mcap"
    f.write_bytes(bytes(data))
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            tr = read_trajectory(f)
    except SensorlessError:
        return "typed", ""
    except Exception as exc:  # noqa: BLE001
        return "generic", f"containers/mcap {kind}: {type(exc).__name__}: {one_line(exc)}"
    if len(tr.t) < N_MSG and not caught:
        return "garbage", f"containers/mcap {kind}: {len(tr.t)} of {N_MSG} samples read, no warning"
    if not (np.all(np.isfinite(tr.q)) and np.all(np.abs(tr.q) < 1e3)):
        return "garbage", f"containers/mcap {kind}: non-finite or huge positions read"
    return "ok", ""


def csv_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    tr = ctx["traj"]
    t = tr.t.copy()
    cols = [t, *tr.q.T, *tr.v.T, *tr.tau.T]
    rows = np.column_stack(cols)
    kind = str(rng.choice(["dup_rows", "dup_stamps", "backwards", "short_last", "few_dups"]))
    if kind == "dup_rows":
        rows = np.repeat(rows, 2, axis=0)
    elif kind == "dup_stamps":  # two different samples per stamp
        rows[1::2, 0] = rows[0::2, 0][: len(rows[1::2])]
    elif kind == "backwards":
        for k in rng.integers(1, len(rows), size=int(rng.integers(1, 4))):
            rows[int(k), 0] = rows[int(k) - 1, 0] - float(rng.uniform(0.001, 1.0))
    elif kind == "few_dups":
        for k in rng.integers(1, len(rows), size=int(rng.integers(1, 4))):
            rows[int(k), 0] = rows[int(k) - 1, 0]
    header = "t,q_j1,q_j2,v_j1,v_j2,tau_j1,tau_j2"
    lines = [header] + [",".join(repr(float(x)) for x in r) for r in rows]
    if kind == "short_last":
        lines[-1] = ",".join(lines[-1].split(",")[: int(rng.integers(1, 7))])
    f = d / "case" / "log.csv"
    f.write_text("\n".join(lines) + "\n")
    written = len(np.unique(rows[:, 0])) - (1 if kind == "short_last" else 0)
    out = d / "case" / "p.npz"
    r = cli(["predict", "--robot", ctx["robot_file"], "--model", ctx["model"], "--data", f, "--out", out])
    outcome, msg = cli_outcome(r, f"containers/csv {kind}")
    if outcome:
        return outcome, msg
    with np.load(out) as z:
        n = len(z["t"])
    if kind in ("dup_rows", "dup_stamps") and not warned(r.output):
        return "garbage", f"containers/csv {kind}: every stamp duplicated, exit 0 without a warning ({n} samples)"
    if n != written and not warned(r.output):
        return "garbage", f"containers/csv {kind}: {n} samples out of {written} written, no warning"
    return "ok", ""


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    (d / "case").mkdir(exist_ok=True)
    return mcap_case(rng, d, ctx) if rng.random() < 0.6 else csv_case(rng, d, ctx)

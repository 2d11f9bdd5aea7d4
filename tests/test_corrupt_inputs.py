"""Corrupt containers and implausible inputs (issue 26 §6): zeroed MCAP chunks, stamps duplicated
throughout, drive gains off the model's torque scale, negative MJCF masses, FIFOs as settings files."""

from __future__ import annotations

import os
import time
import warnings

import numpy as np
import pytest

from sensorless.data import prepare, read_trajectory
from sensorless.data.prepare import load_log
from sensorless.errors import DataError, DataWarning, InputError, RobotModelError, TimestampError, UnitsError
from sensorless.robot import load_robot

TWO_LINK = os.path.join(os.path.dirname(__file__), "data", "two_link.urdf")


# ---- MCAP ------------------------------------------------------------------------------
def _write_mcap(path, n=4000):
    """Joint states only, enough for several 1 MiB chunks."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    JS, Header, Time = (ts.types[k] for k in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header",
                                               "builtin_interfaces/msg/Time"))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        for i in range(n):
            s = 1000.0 + i / 1000.0
            st = Time(sec=int(s), nanosec=int(round((s - int(s)) * 1e9)))
            q = np.array([np.sin(s), np.cos(s), 0.1 * s] + [0.0] * 17)  # long messages: fewer needed per chunk
            msg = JS(header=Header(stamp=st, frame_id=""), name=["j1", "j2", "j3"] + [f"x{k}" for k in range(17)],
                     position=q, velocity=np.zeros(20), effort=np.zeros(20))
            w.write(conn, int(s * 1e9), ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return next(path.glob("*.mcap"))


def _zero_second_chunk(mcap):
    data = bytearray(mcap.read_bytes())
    starts = [i for i in range(8, len(data)) if data[i] == 0x06 and data[i + 9: i + 17] != bytes(8)]
    from rosbags.rosbag2.storage_mcap import McapReader  # the chunk index says where chunks are

    reader = McapReader(mcap)
    reader.open()
    chunks = sorted(c.chunk_start_offset for c in reader.chunks)
    reader.close()
    assert len(chunks) >= 3 and chunks[1] in starts
    off, end = chunks[1], chunks[2]
    data[off:end] = bytes(end - off)
    mcap.write_bytes(bytes(data))
    return off


def test_zeroed_mcap_chunk_is_an_error_naming_it_or_skipped_with_a_count(tmp_path):
    mcap = _write_mcap(tmp_path / "bag")
    assert len(read_trajectory(mcap, joint_names=["j1", "j2", "j3"])) == 4000
    off = _zero_second_chunk(mcap)
    with pytest.raises(DataError, match=rf"corrupt chunk\(s\) at byte offset\(s\) {off} .*'/joint_states': \d+ of "
                                        r"4000 messages lost.*`skip_bad=True`"):
        read_trajectory(mcap, joint_names=["j1", "j2", "j3"])
    with pytest.warns(DataWarning, match=r"`skip_bad=True`: skipped 1 corrupt chunk"):
        traj = read_trajectory(mcap, joint_names=["j1", "j2", "j3"], skip_bad=True, allow_duplicate_times=True)
    assert 0 < len(traj) < 4000


# ---- time stamps -------------------------------------------------------------------------
def test_every_stamp_duplicated_is_refused_with_the_count_and_an_explicit_rate_works(tmp_path):
    t = np.repeat(np.arange(500) / 100.0, 2)
    q = np.sin(t)[:, None] + 0.001 * np.arange(t.size)[:, None] % 2
    path = tmp_path / "dup.csv"
    np.savetxt(path, np.column_stack([t, q]), delimiter=",", header="t,q_a", comments="")
    with pytest.raises(TimestampError, match=r"500 of 999 time steps \(50 %\) repeat.*`resample=RATE_HZ`"):
        load_log(path, None, None, None, None, None, 1)
    out = load_log(path, None, None, None, None, None, 1, resample=100)
    assert len(out) == 500 and out.provenance["resampled"]["duplicates_merged"] == 500


def test_resample_auto_says_what_it_did():
    from sensorless.data import Trajectory

    t = np.arange(400) / 100.0
    t[200:] += 0.004  # one late step: not uniform
    traj = Trajectory(t=t, q=np.sin(t)[:, None], joint_names=("a",), v=np.cos(t)[:, None])
    with pytest.warns(DataWarning, match=r"`resample='auto'`: .*merged 0 duplicate sample\(s\) and interpolated 400 "
                                         r"onto \d+ samples at 100 Hz"):
        prepare(traj, resample="auto")


# ---- drive gains ---------------------------------------------------------------------------
def _current_log(path, gain_true=10.0):
    robot = load_robot(TWO_LINK)
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    tr = synthetic_trajectory(perturbed_truth(robot, rng=0), random_fourier(robot, rng=1, base_freq=0.2).sample(200.0, 10.0),
                              rng=2)
    cols = {"t": tr.t}
    for j, n in enumerate(tr.joint_names):
        cols[f"q_{n}"] = tr.q[:, j]
    for j, n in enumerate(tr.joint_names):
        cols[f"i_{n}"] = tr.tau[:, j] / gain_true
    import pandas as pd

    pd.DataFrame(cols).to_csv(path, index=False)
    return robot


@pytest.mark.parametrize("gain", ["1e6", "1e-4"])
def test_implausible_gains_are_refused_naming_the_joint(tmp_path, gain):
    path = tmp_path / "currents.csv"
    robot = _current_log(path)
    cols = "q=q_{joint};tau=i_{joint}"
    assert load_log(path, robot, cols, None, None, None, 1, gains="10").tau is not None  # the right gain passes
    with pytest.raises(UnitsError, match=r"joint '\w+': drive gain .*`accept_implausible_gains=True`"):
        load_log(path, robot, cols, None, None, None, 1, gains=gain)
    assert load_log(path, robot, cols, None, None, None, 1, gains=gain, accept_implausible_gains=True) is not None


# ---- MJCF ----------------------------------------------------------------------------------
MJCF = """<mujoco model="two_link"><worldbody>
  <body name="link1" pos="0 0 0.1"><joint name="j1" type="hinge" axis="0 0 1"/>
    <inertial pos="0.1 0 0" mass="{m}" diaginertia="{d}"/>
  </body></worldbody></mujoco>"""


@pytest.mark.parametrize("m,d,what", [("-1.5", "0.01 0.02 0.02", "negative mass"),
                                      ("1.5", "0.01 -0.02 0.02", "negative diaginertia")])
def test_mjcf_negative_mass_or_inertia_is_an_error_naming_the_body(tmp_path, m, d, what):
    path = tmp_path / "arm.xml"
    path.write_text(MJCF.format(m="1.5", d="0.01 0.02 0.02"))
    assert load_robot(str(path)).joint_names == ("j1",)
    path.write_text(MJCF.format(m=m, d=d))
    with pytest.raises(RobotModelError, match=rf"body 'link1' inertial has a {what}"):
        load_robot(str(path))


# ---- special files as settings ---------------------------------------------------------------
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_gains_weights_and_config_are_refused_without_blocking(tmp_path):
    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.data.gains import load_gains
    from sensorless.identification import read_weights_file

    fifo = tmp_path / "gains.json"
    os.mkfifo(fifo)
    for call in (lambda: load_gains(str(fifo)), lambda: read_weights_file(fifo, ["a"])):
        start = time.monotonic()
        with pytest.raises(InputError, match="FIFO"):
            call()
        assert time.monotonic() - start < 2
    toml = tmp_path / "run.toml"
    os.mkfifo(toml)
    start = time.monotonic()
    res = CliRunner().invoke(app, ["identify", "--config", str(toml), "--robot", TWO_LINK, "--data", "x.csv",
                                   "--out", str(tmp_path / "o")])
    assert time.monotonic() - start < 2 and res.exit_code == 2 and "FIFO" in res.output


def test_npz_with_an_unknown_compression_method_is_a_data_error(tmp_path):
    """zipfile raises NotImplementedError for it (found by the fuzz run): a typed error, not 'internal'."""
    import struct

    from sensorless.data import read_trajectory
    from sensorless.errors import DataError

    f = tmp_path / "log.npz"
    np.savez(f, t=np.arange(10.0), q=np.zeros((10, 2)))
    data = bytearray(f.read_bytes())
    for sig, off in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):  # local headers and central directory
        i = data.find(sig)
        while i >= 0:
            struct.pack_into("<H", data, i + off, 99)
            i = data.find(sig, i + 4)
    f.write_bytes(bytes(data))
    with pytest.raises(DataError, match="not a readable NPZ"):
        read_trajectory(f)

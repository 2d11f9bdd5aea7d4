"""Bounded readers (issue 26 §3): memory budget, CSV line/field bounds, zip bombs, HDF5
declared sizes and external/virtual storage, special files. Every hostile file is tiny or
written sparsely, and each refusal must come fast."""

from __future__ import annotations

import os
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from sensorless.data import read_trajectory
from sensorless.data.limits import memory_budget, parse_size, read_options
from sensorless.errors import DataError, InputError, OptionError


def _log_npz(path, n=300, joints=3):
    t = np.arange(n) / 100.0
    q = np.sin(np.outer(t, np.arange(1, joints + 1)))
    np.savez(path, times=t, positions=q, velocities=np.cos(q), torques=q)
    return path


def _fast(fn, limit=5.0):
    start = time.monotonic()
    with pytest.raises((InputError, DataError)) as info:
        fn()
    assert time.monotonic() - start < limit
    return str(info.value)


def test_parse_size_and_budget(monkeypatch):
    assert parse_size("8GiB") == 8 << 30
    assert parse_size("500MB") == 500_000_000
    assert parse_size(1e9) == 10**9
    for bad in ("lots", "-1GB", "0", "1 parsec"):
        with pytest.raises(OptionError):
            parse_size(bad)
    monkeypatch.setenv("SENSORLESS_MAX_LOG_MEMORY", "3MiB")
    assert memory_budget() == (3 << 20, "SENSORLESS_MAX_LOG_MEMORY")
    with read_options(max_memory="1GiB"):
        assert memory_budget()[0] == 1 << 30
    monkeypatch.delenv("SENSORLESS_MAX_LOG_MEMORY")
    limit, origin = memory_budget()
    assert 0 < limit <= 4 << 30 and ("available memory" in origin or "default cap" in origin)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_budget_refuses_a_log_over_it_and_reads_it_when_raised(tmp_path, suffix):
    path = _log_npz(tmp_path / "log.npz", n=5000)
    if suffix == ".csv":
        z = np.load(path)
        data = np.column_stack([z["times"], z["positions"]])
        path = tmp_path / "log.csv"
        np.savetxt(path, data, delimiter=",", header="t,q_a,q_b,q_c", comments="")
    msg = _fast(lambda: read_trajectory(path, max_memory="100KB"))
    assert str(path) in msg and "`max_memory=SIZE`" in msg and "split the log" in msg and "100.0 KiB" not in msg
    assert len(read_trajectory(path, max_memory="1GiB")) == 5000


def test_env_budget_reaches_the_reader(tmp_path, monkeypatch):
    path = _log_npz(tmp_path / "log.npz", n=5000)
    monkeypatch.setenv("SENSORLESS_MAX_LOG_MEMORY", "50KB")
    assert "SENSORLESS_MAX_LOG_MEMORY" in _fast(lambda: read_trajectory(path))


def test_npz_zip_bomb_is_refused_by_member_name(tmp_path):
    path = tmp_path / "bomb.npz"
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (5_000_000, 7)  # 280 MB of zeros, deflated to 0.3 MB
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open("positions.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, header)
            block = bytes(1 << 22)
            for _ in range(5_000_000 * 7 * 8 // len(block)):
                fh.write(block)
            fh.write(bytes(5_000_000 * 7 * 8 % len(block)))
    assert path.stat().st_size < 1e6
    msg = _fast(lambda: read_trajectory(path, max_memory="100MB"))
    assert "'positions'" in msg and "zip bomb" in msg and "267.0 MiB" in msg


def test_npz_header_larger_than_member_is_corrupt(tmp_path):
    path = tmp_path / "lie.npz"
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (10**12,)
    with zipfile.ZipFile(path, "w") as zf:
        with zf.open("positions.npy", "w") as fh:
            np.lib.format.write_array_header_1_0(fh, header)
            fh.write(bytes(80))
    msg = _fast(lambda: read_trajectory(path))
    assert "positions" in msg and "corrupt" in msg


def test_hdf5_declared_size_is_checked_before_reading(tmp_path):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "huge.h5"
    with h5py.File(path, "w") as f:  # a few KB on disk, 10¹⁰ float64 declared
        f.create_dataset("positions", shape=(10**9, 10), dtype="f8", chunks=(1000, 10))
        f.create_dataset("times", shape=(10**9,), dtype="f8", chunks=(1000,))
    assert path.stat().st_size < 50_000
    msg = _fast(lambda: read_trajectory(path))
    assert str(path) in msg and "`max_memory=SIZE`" in msg


def test_hdf5_external_and_virtual_datasets_are_refused_unless_allowed(tmp_path):
    h5py = pytest.importorskip("h5py")
    secret = tmp_path / "secret.bin"
    secret.write_bytes(np.arange(300.0).tobytes())
    ext = tmp_path / "ext.h5"
    with h5py.File(ext, "w") as f:
        f["times"] = np.arange(300) / 100.0
        f.create_dataset("positions", shape=(300, 1), dtype="<f8", external=[(str(secret), 0, 2400)])
    msg = _fast(lambda: read_trajectory(ext))
    assert "'positions'" in msg and "external raw storage" in msg and "`allow_external=True`" in msg
    assert read_trajectory(ext, allow_external=True).q[5, 0] == 5.0

    vds = tmp_path / "vds.h5"
    layout = h5py.VirtualLayout(shape=(300, 1), dtype="f8")
    layout[:] = h5py.VirtualSource(str(tmp_path / "missing.h5"), "data", shape=(300, 1))
    with h5py.File(vds, "w") as f:
        f["times"] = np.arange(300) / 100.0
        f.create_virtual_dataset("positions", layout, fillvalue=0)
    msg = _fast(lambda: read_trajectory(vds))
    assert "'positions'" in msg and "virtual dataset" in msg


def test_csv_with_a_40mb_line_is_refused_fast(tmp_path):
    path = tmp_path / "oneline.csv"
    path.write_bytes(b"t," + b"1.0," * 10_000_000 + b"\n")
    msg = _fast(lambda: read_trajectory(path))
    assert str(path) in msg and "line 1" in msg and "MiB" in msg


def test_csv_header_of_150000_fields_is_refused_fast(tmp_path):
    path = tmp_path / "wide.csv"
    path.write_text(",".join(f"{i % 1000:03d}" for i in range(150_000)) + "\n" + ",".join(["1"] * 150_000) + "\n")
    assert path.stat().st_size < 1 << 20
    msg = _fast(lambda: read_trajectory(path))
    assert "line 1 has 150000 fields" in msg


def test_parquet_column_of_bytes_is_a_typed_error(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    path = tmp_path / "bytes.parquet"
    t = np.arange(100) / 100.0
    pq.write_table(pa.table({"t": t, "q_a": [b"\xff\xfe" for _ in t], "q_b": np.sin(t)}), path)
    with pytest.raises(DataError, match="column 'q_a' .*holds bytes"):
        read_trajectory(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_log_is_refused_without_blocking(tmp_path):
    for name in ("log.csv", "log.npz", "log.mcap"):
        fifo = tmp_path / name
        os.mkfifo(fifo)
        msg = _fast(lambda: read_trajectory(fifo), limit=2.0)
        assert "FIFO" in msg


def test_cli_max_log_memory_refuses_in_one_line_and_bad_sizes_are_option_errors(tmp_path):
    from typer.testing import CliRunner

    from sensorless.cli import app

    log = _log_npz(tmp_path / "log.npz", n=5000, joints=2)
    urdf = os.path.join(os.path.dirname(__file__), "data", "two_link.urdf")
    base = ["identify", "--robot", urdf, "--data", str(log), "--method", "ols", "--out", str(tmp_path / "o")]
    res = CliRunner().invoke(app, base + ["--max-log-memory", "100KB"])
    assert res.exit_code == 2 and "log too large for memory" in res.output and "--max-log-memory" in res.output
    assert not (tmp_path / "o").exists()
    res = CliRunner().invoke(app, base + ["--max-log-memory", "lots"])
    assert res.exit_code == 2 and "--max-log-memory must be a size" in res.output


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_ten_million_rows_are_refused_within_seconds(tmp_path, suffix, monkeypatch):
    """10⁷ rows × 7 joints (t, q, v, tau): ~7 GB through the pipeline; over a 4 GiB budget it is refused
    before anything is allocated (the default budget is a quarter of the available memory)."""
    n, f = 10_000_000, np.arange(1, 8) * 0.05
    path = tmp_path / f"big{suffix}"
    if suffix == ".npz":
        t = np.arange(n) / 1000.0
        np.savez(path, times=t, positions=np.sin(np.outer(t, f)), velocities=np.cos(np.outer(t, f)),
                 torques=np.sin(np.outer(t, f) + 1))
    else:
        with open(path, "w") as fh:
            fh.write(",".join(["t"] + [f"{w}_j{i}" for w in ("q", "v", "tau") for i in range(7)]) + "\n")
            for s in range(0, n, 1_000_000):
                t = np.arange(s, s + 1_000_000) / 1000.0
                ph = np.outer(t, f)
                np.savetxt(fh, np.column_stack([t, np.sin(ph), np.cos(ph), np.sin(ph + 1)]), fmt="%.9g", delimiter=",")
    monkeypatch.setenv("SENSORLESS_MAX_LOG_MEMORY", "4GiB")
    msg = _fast(lambda: read_trajectory(path), limit=60.0)
    assert "log too large for memory" in msg and "4.0 GiB" in msg


@pytest.mark.skipif(not Path("/proc/meminfo").exists(), reason="reads /proc/meminfo (Linux)")
def test_available_memory_is_psutils_figure_without_importing_it():
    """The budget of a log read comes from /proc/meminfo, the figure psutil reports on Linux (issue 28:
    psutil's import was ~10 ms of every identify)."""
    import subprocess
    import sys

    code = ("import sys\nfrom sensorless.data.limits import available_memory\na = available_memory()\n"
            "print('psutil' in sys.modules)\nimport psutil\nprint(abs(a - psutil.virtual_memory().available) / a)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    loaded, diff = out.stdout.split()
    assert loaded == "False" and float(diff) < 0.05  # the same counter, read a few ms apart

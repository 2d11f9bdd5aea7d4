"""The log-format registry (sensorless.data.formats): every format claims its own files, the reader
dispatches through it, and the Arrow IPC / Feather format reads the same log as Parquet and CSV."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sensorless.data import read_trajectory
from sensorless.data.formats import FORMATS, SUPPORTED_EXTENSIONS, LogFormat, find_format, formats_help
from sensorless.errors import DataError, DataWarning


def test_registry_is_consistent(tmp_path):
    names = [f.name for f in FORMATS]
    assert len(set(names)) == len(names)
    owners = [s for f in FORMATS for s in f.suffixes]
    assert len(owners) == len(set(owners)) == len(SUPPORTED_EXTENSIONS)  # one format per suffix
    for f in FORMATS:
        assert isinstance(f, LogFormat) and f.description in formats_help()
        for s in f.suffixes:
            p = tmp_path / f"log{s}"
            p.write_bytes(b"")
            assert find_format(p) is f, s
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("x")
    assert find_format(tmp_path / "bag").name == "rosbag"  # before the per-signal folder
    assert find_format(tmp_path).name == "folder"
    assert find_format(tmp_path / "log.xlsx") is None


@pytest.fixture(scope="module")
def frame():
    rng = np.random.default_rng(4)
    n = 300
    t = np.arange(n) / 100.0
    cols = {"t": t}
    for j in ("a", "b"):
        cols[f"q_{j}"] = np.sin(t + rng.uniform())
        cols[f"dq_{j}"] = rng.normal(size=n)
        cols[f"tau_{j}"] = rng.normal(size=n)
    return pd.DataFrame(cols)


def _fields(tr):
    return {k: getattr(tr, k) for k in ("t", "q", "v", "tau")}


def test_arrow_feather_and_stream_read_as_parquet_and_csv(frame, tmp_path):
    import pyarrow as pa

    csv = tmp_path / "log.csv"
    frame.to_csv(csv, index=False, float_format="%.17g")
    frame.to_parquet(tmp_path / "log.parquet")
    frame.to_feather(tmp_path / "log.feather")
    table = pa.Table.from_pandas(frame, preserve_index=False)
    with pa.OSFile(str(tmp_path / "log.arrow"), "wb") as sink, pa.ipc.new_stream(sink, table.schema) as w:
        w.write_table(table)  # the IPC stream layout
    ref = read_trajectory(csv)
    assert ref.joint_names == ("a", "b")
    for name in ("log.parquet", "log.feather", "log.arrow"):
        tr = read_trajectory(tmp_path / name)
        assert tr.joint_names == ref.joint_names
        for k, x in _fields(ref).items():
            np.testing.assert_array_equal(getattr(tr, k), x, err_msg=f"{name}: {k}")


def test_arrow_column_map_unused_columns_and_a_corrupt_file(frame, tmp_path):
    f = frame.assign(motor_temp=40.0)
    f.to_feather(tmp_path / "log.feather")
    with pytest.warns(DataWarning, match="motor_temp"):
        tr = read_trajectory(tmp_path / "log.feather")
    np.testing.assert_array_equal(tr.q[:, 1], frame["q_b"].to_numpy())
    with pytest.warns(DataWarning, match="q_a"):
        tr = read_trajectory(tmp_path / "log.feather", columns={"q": ["q_b"], "v": ["dq_b"], "tau": ["tau_b"]},
                             joint_names=["b"])
    np.testing.assert_array_equal(tr.tau[:, 0], frame["tau_b"].to_numpy())
    bad = tmp_path / "bad.arrow"
    bad.write_bytes(b"not arrow at all")
    with pytest.raises(DataError, match=r"bad\.arrow: not a readable Arrow IPC / Feather file"):
        read_trajectory(bad)

"""MATLAB .mat logs (v7.3 via h5py, v5/v7 via scipy) and the orientation of stored arrays
(sensorless.data.matlab, sensorless.data.orientation)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from matlab_writer import CellStr, MatlabString, write_mat73
from sensorless.data import read_trajectory
from sensorless.errors import DataError, DataWarning, ShapeMismatchError

NAMES = ("shoulder", "elbow", "wrist")


def _log(n: int = 300, k: int = 3, rate: float = 200.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    w = 2 * np.pi * rng.uniform(0.3, 1.0, k)
    q = 0.7 * np.sin(w * t[:, None])
    return t, q, 0.7 * w * np.cos(w * t[:, None]), rng.normal(size=(n, k))


def _quiet(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return read_trajectory(path, **kw)


def test_v73_char_matrix_names_and_struct_paths(tmp_path):
    """Two runs in one file as structs: without --columns the name 'q' is ambiguous (both at the
    same depth) and the error says how to choose; 'q=run2/q' picks one; a char matrix of
    blank-padded names decodes."""
    t, q, v, tau = _log()
    path = write_mat73(tmp_path / "two.mat", {
        "run1": {"t": t, "q": q, "tau": tau}, "run2": {"t": t, "q": 2 * q, "tau": -tau},
        "joint_names": list(NAMES)})
    with pytest.raises(DataError, match=r"ambiguous 't'.*run1/t.*`columns=\{'t': 'run1/t'\}`"):
        read_trajectory(path)
    cols = {"t": "run2/t", "q": "run2/q", "tau": "run2/tau"}
    with pytest.warns(DataWarning, match=r"variables not used: 'run1/q', 'run1/t', 'run1/tau'"):
        tr = read_trajectory(path, columns=cols)
    assert tr.joint_names == NAMES
    np.testing.assert_array_equal(tr.q, 2 * q)
    np.testing.assert_array_equal(tr.tau, -tau)


def test_v73_string_array_names_are_refused_with_the_fix(tmp_path):
    t, q, _, tau = _log()
    path = write_mat73(tmp_path / "s.mat", {"t": t, "q": q, "tau": tau, "joint_names": MatlabString(NAMES)})
    with pytest.raises(DataError, match=r"'joint_names' is a MATLAB string array.*cellstr\(names\).*char\(names\)"):
        read_trajectory(path)


def test_v73_file_named_h5_is_read_as_matlab(tmp_path):
    """The issue's workaround (rename to .h5) used to read MATLAB's reversed arrays as is."""
    t, q, v, tau = _log()
    path = write_mat73(tmp_path / "log.h5", {"t": t, "q": q, "v": v, "tau": tau, "joint_names": CellStr(NAMES)})
    tr = read_trajectory(path)
    assert tr.joint_names == NAMES and tr.q.shape == q.shape
    np.testing.assert_array_equal(tr.v, v)
    assert "layout" not in tr.units  # MATLAB's own order: nothing stored channels × samples


def test_v5_mat_struct_cellstr_and_channel_major(tmp_path):
    """scipy.io.savemat (v5): the struct's fields by path, a 1 × N time row, q saved one row
    per joint (channels × samples) is transposed, cellstr names decode."""
    from scipy.io import savemat

    t, q, v, tau = _log()
    savemat(tmp_path / "v5.mat", {"data": {"time": t[None, :], "q": q.T, "qd": v, "torque": tau,
                                           "names": np.array(NAMES, dtype=object)}})
    tr = read_trajectory(tmp_path / "v5.mat")
    assert tr.joint_names == NAMES and "q" in tr.units["layout"]
    np.testing.assert_array_equal(tr.t, t)
    np.testing.assert_array_equal(tr.q, q)
    np.testing.assert_array_equal(tr.v, v)
    np.testing.assert_array_equal(tr.tau, tau)


def test_v5_text_where_numbers_are_expected_names_the_variable(tmp_path):
    from scipy.io import savemat

    t, q, _, _ = _log()
    savemat(tmp_path / "bad.mat", {"t": t, "q": q, "tau": "not numbers"})
    with pytest.raises(DataError, match=r"'tau' holds text"):
        read_trajectory(tmp_path / "bad.mat")


def test_channel_major_hdf5_is_transposed_by_the_time_length(tmp_path):
    import h5py

    t, q, v, tau = _log()
    with h5py.File(tmp_path / "cm.h5", "w") as f:
        f["t"], f["q"], f["v"], f["tau"] = t, q.T, v.T, tau  # tau already sample-major
    tr = read_trajectory(tmp_path / "cm.h5")
    np.testing.assert_array_equal(tr.q, q)
    np.testing.assert_array_equal(tr.v, v)
    np.testing.assert_array_equal(tr.tau, tau)
    assert tr.units["layout"] == "stored channels × samples, transposed: q, v"


def test_without_time_the_joint_count_decides(tmp_path, ur5):
    """No time vector: the axis of q that is not the robot's joint count is time (with --rate)."""
    n = len(ur5.joint_names)
    rng = np.random.default_rng(1)
    q = 0.3 * np.sin(np.linspace(0, 6, 2 * n)[:, None] + rng.uniform(0, 1, n))  # few samples: 2n
    np.savez(tmp_path / "cm.npz", q=q.T, tau=rng.normal(size=(n, 2 * n)))
    tr = _quiet(tmp_path / "cm.npz", robot=ur5, rate=100.0)
    assert tr.q.shape == (2 * n, n)
    np.testing.assert_array_equal(tr.q, q)


def test_square_array_is_an_error_naming_it(tmp_path):
    """As many samples as channels: neither axis can be told to be time."""
    t, q, _, _ = _log(n=3, k=3)
    write_mat73(tmp_path / "sq.mat", {"log": {"t": t, "q": q}})
    with pytest.raises(ShapeMismatchError, match=r"array 'log/q' is 3 × 3 .*cannot tell which axis is time"):
        read_trajectory(tmp_path / "sq.mat")


def test_corrupt_mat_is_a_data_error(tmp_path):
    (tmp_path / "x.mat").write_bytes(b"MATLAB 5.0 MAT-file" + b"\x00" * 50)
    with pytest.raises(DataError, match="x.mat"):
        read_trajectory(tmp_path / "x.mat")
    (tmp_path / "y.mat").write_bytes(b"MATLAB 7.3 MAT-file, but not HDF5")
    with pytest.raises(DataError, match="y.mat: not a readable MATLAB v7.3"):
        read_trajectory(tmp_path / "y.mat")


def test_v5_numeric_or_mixed_joint_names_are_refused_like_v73(tmp_path):
    """Fuzz class ``formats``: a v5 ``joint_names`` of numbers read as names '1.0', '2.0' with exit 0
    (v7.3 refuses the same variable); a count that differs from q's columns names both, in flag words."""
    from scipy.io import savemat

    t, q, _, tau = _log(k=2)
    for names, why in ((np.array([1.0, 2.0]), r"'joint_names' holds float64 values, not text"),
                       (np.array([1.5, "x"], dtype=object), r"'joint_names' is a cell array whose items are not all "
                                                              r"text \(one is float 1.5\)")):
        savemat(tmp_path / "n.mat", {"t": t, "q": q, "tau": tau, "joint_names": names})
        with pytest.raises(DataError, match=why):
            read_trajectory(tmp_path / "n.mat")
    write_mat73(tmp_path / "n73.mat", {"t": t, "q": q, "tau": tau, "joint_names": np.array([1.0, 2.0])})
    with pytest.raises(DataError, match=r"'joint_names' holds double values, not text"):
        read_trajectory(tmp_path / "n73.mat")
    savemat(tmp_path / "three.mat", {"t": t, "q": q, "joint_names": np.array(NAMES, dtype=object)})
    with pytest.raises(ShapeMismatchError, match=r"joint names are 3 \('shoulder', 'elbow', 'wrist'\) but 'q' \('q'\) "
                                                 r"has 2 columns.*`columns=\{'q': '\.\.\.'\}`") as err:
        read_trajectory(tmp_path / "three.mat")
    assert "pass joint_names" not in str(err.value)

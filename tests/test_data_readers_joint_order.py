"""Issue 40: a log whose joints come in its own order. A MATLAB file holding its joint names under its own
variable name (a cell array, a char matrix or a MATLAB ``string``) was read in the model's order (neck data on
the hips, exit 0). The names are mapped with ``columns={"joint_names": NAME}`` (``--columns joint_names=NAME``)
and the columns matched by name; a log whose names were not read while the file holds text is refused unless
the model's order is confirmed (``--joint-order model``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.io
from typer.testing import CliRunner

from matlab_writer import CellStr, MatlabString, write_mat73
from sensorless.cli import app
from sensorless.data import read_trajectory
from sensorless.data.limits import read_options
from sensorless.errors import DataError, DataWarning

LOG_ORDER = ["wrist_3_joint", "wrist_2_joint", "wrist_1_joint", "elbow_joint", "shoulder_lift_joint",
             "shoulder_pan_joint"]  # the log's own order: the model's reversed


def _arrays(n=400, rate=100.0):
    t = np.arange(n) / rate
    q = np.column_stack([0.1 * (k + 1) * np.sin((k + 1) * t) for k in range(6)])  # column k = LOG_ORDER[k]
    return t, q


def _read(path, ur5, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return read_trajectory(path, robot=ur5, **kw)


@pytest.mark.parametrize("kind", ["v5-cell", "v73-cell", "v73-char"])
def test_names_under_the_files_own_name_are_mapped_and_the_columns_matched_by_name(tmp_path, ur5, kind):
    t, q = _arrays()
    path = tmp_path / "est.mat"
    if kind == "v5-cell":
        scipy.io.savemat(path, {"t": t, "estimatorJointsPos": q,
                                "estimatorJointNames": np.array(LOG_ORDER, dtype=object)})
    else:
        names = CellStr(LOG_ORDER) if kind == "v73-cell" else list(LOG_ORDER)  # a list: a char matrix
        write_mat73(path, {"t": t, "estimatorJointsPos": q, "estimatorJointNames": names})
    cols = {"q": "estimatorJointsPos"}
    with pytest.raises(DataError, match=r"holds text \['estimatorJointNames'\].*`columns=\{'joint_names': "
                                        r"'estimatorJointNames'\}`.*`joint_order='model'`"):
        _read(path, ur5, columns=cols)
    tr = _read(path, ur5, columns={**cols, "joint_names": "estimatorJointNames"})
    assert list(tr.joint_names) == list(ur5.joint_names)
    for k, name in enumerate(LOG_ORDER):  # each column landed on its own joint
        np.testing.assert_allclose(tr.q[:, list(tr.joint_names).index(name)], q[:, k])
    with read_options(joint_order="model"):  # confirmed: the model's order, as written
        tr = _read(path, ur5, columns=cols)
    np.testing.assert_allclose(tr.q, q)


def test_a_matlab_string_of_names_is_refused_with_the_fix_when_mapped_and_the_order_refused_when_not(tmp_path, ur5):
    t, q = _arrays()
    path = write_mat73(tmp_path / "s.mat", {"t": t, "estimatorJointsPos": q,
                                            "estimatorJointNames": MatlabString(LOG_ORDER)})
    with pytest.raises(DataError, match=r"holds text \['estimatorJointNames'\]"):
        _read(path, ur5, columns={"q": "estimatorJointsPos"})
    with pytest.raises(DataError, match=r"'estimatorJointNames' is a MATLAB string array.*cellstr"):
        _read(path, ur5, columns={"q": "estimatorJointsPos", "joint_names": "estimatorJointNames"})


def test_npz_text_array_and_the_cli_flags(tmp_path, ur5):
    t, q = _arrays()
    path = tmp_path / "log.npz"
    np.savez(path, t=t, q=q, tau=np.zeros_like(q), labels=np.array(LOG_ORDER))
    res = CliRunner().invoke(app, ["predict", "--robot", "ur5", "--data", str(path), "--out", str(tmp_path / "p.npz")])
    assert res.exit_code != 0 and "--columns joint_names=labels" in " ".join(res.output.split()), res.output
    assert "--joint-order model" in " ".join(res.output.split()) and not (tmp_path / "p.npz").exists()
    res = CliRunner().invoke(app, ["predict", "--robot", "ur5", "--data", str(path), "--columns", "joint_names=labels",
                                   "--out", str(tmp_path / "p.npz")])
    assert res.exit_code == 0, res.output
    np.savez(tmp_path / "plain.npz", t=t, q=q, tau=np.zeros_like(q))  # no text at all: the model's order, as before
    assert list(_read(tmp_path / "plain.npz", ur5).joint_names) == list(ur5.joint_names)


def test_joint_names_in_a_table_map_is_refused_naming_the_header(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("t,q_a,q_b\n0,0,0\n0.01,0,0\n")
    with pytest.raises(DataError, match=r"only array files hold.*pos_\{joint\}"):
        read_trajectory(path, columns={"q": "q_{joint}", "joint_names": "x"})

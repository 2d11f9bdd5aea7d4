"""Logs from other tools: header naming conventions found without ``columns``, and joint-name
errors that say what to do (did-you-mean, --lock for joints absent from the log)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sensorless.data import read_trajectory
from sensorless.data.tabular import detect_patterns
from sensorless.errors import DataError, JointNameError
from sensorless.robot import load_robot

JOINTS = ("shoulder", "elbow")


def _write(path, names: dict[str, str], extra: dict | None = None):
    """A 50-sample log with field f of joint j in column names[f].format(j); values encode
    (field, joint) so that a wrong mapping shows."""
    t = np.arange(50) * 0.01
    cols = {"time": t}
    for k, (field, fmt) in enumerate(names.items()):
        for j, joint in enumerate(JOINTS):
            cols[fmt.format(joint)] = (10 * k + j) + 0.01 * np.sin(t)
    cols.update(extra or {})
    pd.DataFrame(cols).to_csv(path, index=False)


@pytest.mark.parametrize("names", [
    {"q": "{}_pos", "v": "{}_vel", "tau": "{}_eff"},
    {"q": "{}.position", "v": "{}.velocity", "tau": "{}.effort"},
    {"q": "pos_{}", "v": "vel_{}", "tau": "torque_{}"},
    {"q": "q_{}", "v": "v_{}", "tau": "tau_{}"},
    {"q": "{}/position", "v": "{}/velocity", "tau": "{}/effort"},
])
def test_common_header_conventions_are_read_without_columns(tmp_path, names):
    _write(tmp_path / "log.csv", names)
    tr = read_trajectory(tmp_path / "log.csv")
    assert tr.joint_names == JOINTS
    for k, field in enumerate(names):
        np.testing.assert_allclose(getattr(tr, field).mean(axis=0), [10 * k, 10 * k + 1], atol=0.01)


def test_qualified_columns_do_not_become_joints(tmp_path):
    """q_cmd_J next to q_J is J's command, not a joint named 'cmd_J'."""
    _write(tmp_path / "log.csv", {"q": "q_{}", "v": "v_{}", "command": "q_cmd_{}"})
    tr = read_trajectory(tmp_path / "log.csv")
    assert tr.joint_names == JOINTS and tr.extras["command"].shape == (50, 2)


def test_currents_in_a_convention_are_found():
    spec = detect_patterns(["t", "pos_a", "pos_b", "vel_a", "vel_b", "cur_a", "cur_b"])
    assert spec["q"] == "pos_{joint}" and spec["v"] == "vel_{joint}" and spec["current"] == "cur_{joint}"
    assert detect_patterns(["t", "x", "y"]) is None


def test_unreadable_header_says_how_to_map_columns(tmp_path):
    pd.DataFrame({"t": np.arange(5.0), "x": np.zeros(5)}).to_csv(tmp_path / "log.csv", index=False)
    with pytest.raises(DataError, match=r"`columns=\{'q': 'pos_\{joint\}'"):
        read_trajectory(tmp_path / "log.csv")


def test_comma_separated_column_list_is_pointed_to_the_bar(tmp_path):
    _write(tmp_path / "log.csv", {"q": "{}_pos", "v": "{}_vel"})
    with pytest.raises(DataError, match=r"separated by '\|'"):
        read_trajectory(tmp_path / "log.csv", columns={"q": "shoulder_pos,elbow_pos"})


def test_joint_name_errors_suggest_the_fix():
    ur5 = load_robot("ur5")
    with pytest.raises(JointNameError, match=r"`lock_joints=\['wrist_2_joint', 'wrist_3_joint'\]`"):
        ur5.joint_order(list(ur5.joint_names[:4]))
    renamed = ["ur_" + n for n in ur5.joint_names]
    with pytest.raises(JointNameError, match="for 'ur_elbow_joint', did you mean 'elbow_joint'"):
        ur5.joint_order(renamed)


@pytest.mark.parametrize("unit, scale", [("ns", 1e9), ("us", 1e6), ("ms", 1e3)])
def test_epoch_stamps_in_sub_second_units_are_converted(tmp_path, unit, scale):
    """ROS CSV exports (`rostopic echo -p`: '%time' in ns) and ms/µs epoch stamps: the unit is
    told by magnitude, converted to s and recorded."""
    t = 1.7e9 + np.arange(60) * 0.005
    q = np.sin(np.arange(60) * 0.01)
    pd.DataFrame({"%time": (t * scale).astype("int64"), "q_a": q, "q_b": q}).to_csv(tmp_path / "log.csv", index=False)
    tr = read_trajectory(tmp_path / "log.csv")
    assert tr.rate == pytest.approx(200.0, rel=1e-3) and f"converted from {unit}" in tr.units["t"]
    np.testing.assert_allclose(tr.t - tr.t[0], np.arange(60) * 0.005, atol=1e-6)


def test_relative_stamps_in_ms_are_a_units_error(tmp_path):
    from sensorless.errors import UnitsError

    pd.DataFrame({"t": np.arange(60) * 5.0, "q_a": np.zeros(60)}).to_csv(tmp_path / "log.csv", index=False)
    with pytest.raises(UnitsError, match=r"look like ms \(then 200 Hz\).*time_unit='ms'"):
        read_trajectory(tmp_path / "log.csv")
    assert read_trajectory(tmp_path / "log.csv", time_unit="ms").rate == pytest.approx(200.0)


def test_cli_time_unit_is_used_and_remembered_by_the_model(tmp_path):
    """--time-unit ms reads relative millisecond stamps; predict reuses it from result.json."""
    import json

    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    ur5 = load_robot("ur5")
    tr = synthetic_trajectory(perturbed_truth(ur5, rng=1), random_fourier(ur5, rng=2).sample(100.0, 15.0),
                              noise_std=0.02, rng=3)
    cols = {"t": tr.t * 1e3}
    for j, n in enumerate(tr.joint_names):
        cols.update({f"{n}_pos": tr.q[:, j], f"{n}_vel": tr.v[:, j], f"{n}_eff": tr.tau[:, j]})
    pd.DataFrame(cols).to_csv(tmp_path / "log.csv", index=False)
    run = CliRunner().invoke
    r = run(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "log.csv"), "--out", str(tmp_path / "m"),
                  "--method", "ols", "--no-plot"])
    assert r.exit_code == 2 and "--time-unit ms" in r.output and not (tmp_path / "m").exists()
    r = run(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "log.csv"), "--out", str(tmp_path / "m"),
                  "--method", "ols", "--no-plot", "--time-unit", "ms"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "m" / "result.json").read_text())["settings"]["preprocessing"]["time_unit"] == "ms"
    r = run(app, ["predict", "--robot", "ur5", "--model", str(tmp_path / "m"), "--data", str(tmp_path / "log.csv"),
                  "--out", str(tmp_path / "p.npz")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "p.npz")
    np.testing.assert_allclose(z["t"] - z["t"][0], tr.t[: len(z["t"])] - tr.t[0], atol=1e-9)
    assert np.sqrt(np.mean((z["tau_pred"] - z["tau_measured"]) ** 2)) < 0.1


def test_plotjuggler_csv_export_is_read_without_columns(tmp_path):
    """PlotJuggler: '__time' and '/topic/JOINT/position' columns; the topic path is not part of the name."""
    t = 1.7e9 + np.arange(40) * 0.01
    cols = {"__time": t}
    for k, joint in enumerate(JOINTS):
        for m, word in enumerate(("position", "velocity", "effort")):
            cols[f"/joint_states/{joint}/{word}"] = np.full(40, 10.0 * m + k)
    pd.DataFrame(cols).to_csv(tmp_path / "pj.csv", index=False)
    tr = read_trajectory(tmp_path / "pj.csv")
    assert tr.joint_names == JOINTS and tr.rate == pytest.approx(100.0)
    assert (tr.q[0].tolist(), tr.v[0].tolist(), tr.tau[0].tolist()) == ([0, 1], [10, 11], [20, 21])


def test_rostopic_echo_csv_of_joint_states_is_read_without_columns(tmp_path):
    """`rostopic echo -p /joint_states`: '%time' in ns, joint names in field.nameI, values in
    field.positionI / velocityI / effortI (here in another order than the robot's)."""
    n = 40
    cols = {"%time": ((1.7e9 + np.arange(n) * 0.005) * 1e9).astype("int64"), "field.header.seq": np.arange(n)}
    order = JOINTS[::-1]
    for i, joint in enumerate(order):
        cols[f"field.name{i}"] = joint
    for m, word in enumerate(("position", "velocity", "effort")):
        for i, joint in enumerate(order):
            cols[f"field.{word}{i}"] = np.full(n, 10.0 * m + JOINTS.index(joint))
    pd.DataFrame(cols).to_csv(tmp_path / "rt.csv", index=False)
    tr = read_trajectory(tmp_path / "rt.csv")
    assert tr.joint_names == order and tr.rate == pytest.approx(200.0, rel=1e-3)
    assert tr.tau[0].tolist() == [21, 20] and "converted from ns" in tr.units["t"]
    cols["field.name0"] = [order[0]] * (n - 1) + ["other"]
    pd.DataFrame(cols).to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(DataError, match="field.name0' changes within the log"):
        read_trajectory(tmp_path / "bad.csv")

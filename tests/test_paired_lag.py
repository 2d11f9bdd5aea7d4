"""Paired runs recorded at different times: the lag is found from the positions, applied and
reported, and a pair that is not one trajectory is refused (drive-gains and payload --align time)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import Trajectory
from sensorless.data.align import estimate_lag
from sensorless.errors import DataError
from sensorless.simulation.current_arm import drive_gains_for, simulate, truth_model, with_payload

COLS = "q=pos_{joint};v=vel_{joint};tau=i_{joint}"
LAG = 1.2


@pytest.fixture(scope="module")
def shifted_pair(tmp_path_factory):
    """An unloaded and a loaded run of one trajectory; the loaded run starts its excitation 1.2 s later."""
    d = tmp_path_factory.mktemp("pair")
    robot, truth = truth_model("ur10", 0, stribeck=True, friction_scale=4.0)
    K = drive_gains_for(robot)
    kw = dict(motion=10.0, idle_end=1.0, ramp=1.0, motion_seed=30)
    simulate(robot, truth, K, seed=3, idle_start=1.5, **kw).to_csv(d / "u.csv", index=False)
    simulate(robot, with_payload(truth, "tool0", 4.0), K, seed=4, idle_start=1.5 + LAG, **kw).to_csv(
        d / "l.csv", index=False)
    return d, robot, K


def test_coarse_lag_of_a_shifted_pair_within_a_sample():
    t = np.arange(3000) / 100.0
    f = lambda s: np.column_stack([np.sin(0.7 * s) * (s > 2), 0.5 * np.cos(1.3 * s) * (s > 2)])  # noqa: E731
    ref = Trajectory(t=t, q=f(t), joint_names=("a", "b"))
    load = Trajectory(t=t + 100.0, q=f(t - 1.234), joint_names=("a", "b"))  # starts 1.234 s later
    lag = estimate_lag(load, ref)
    assert lag.seconds == pytest.approx(-1.234, abs=0.01) and lag.correlation > 0.99


def test_two_different_trajectories_are_refused():
    t = np.arange(2000) / 100.0
    rng = np.random.default_rng(0)
    ref = Trajectory(t=t, q=np.cumsum(rng.normal(size=(2000, 2)), axis=0), joint_names=("a", "b"), source="u.csv")
    load = Trajectory(t=t, q=np.cumsum(rng.normal(size=(2000, 2)), axis=0), joint_names=("a", "b"), source="l.csv")
    with pytest.raises(DataError, match=r"l.csv.*not look like the same trajectory as u.csv"):
        estimate_lag(load, ref)


def test_drive_gains_on_a_pair_shifted_by_1_2_s_within_2_percent_with_the_lag_reported(shifted_pair, tmp_path):
    d, robot, K = shifted_pair
    out = tmp_path / "k.json"
    r = CliRunner().invoke(app, ["drive-gains", "--robot", "ur10", "--unloaded", str(d / "u.csv"), "--loaded",
                                 str(d / "l.csv"), "--columns", COLS, "--trim", "1.5:-1", "--savgol-window", "21",
                                 "--payload-mass", "4", "--frame", "tool0", "--com", "0.06,0.02,0.05", "--n-boot", "100",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    gains = np.array([doc["estimated_gains"][j] for j in robot.actuated_joints])
    assert np.all(np.abs(gains / K - 1) < 0.02), gains / K
    lag = doc["diagnostics"]["alignment"]
    assert lag["lag_s"] == pytest.approx(-LAG, abs=0.02) and lag["correlation"] > 0.95
    assert "lag" in r.output


def test_payload_from_a_pair_shifted_by_1_2_s_within_3_percent(shifted_pair, tmp_path):
    d, robot, K = shifted_pair
    gains = tmp_path / "K.json"
    gains.write_text(json.dumps(dict(zip(robot.actuated_joints, map(float, K)))))
    common = ["--robot", "ur10", "--columns", COLS, "--savgol-window", "21", "--trim", "1.5:-1"]
    r = CliRunner().invoke(app, ["identify", *common, "--data", str(d / "u.csv"), "--gains", str(gains),
                                 "--method", "ols", "--no-plot", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(app, ["payload", *common, "--model", str(tmp_path / "m"), "--data", str(d / "l.csv"),
                                 "--no-load", str(d / "u.csv"), "--align", "time", "--frame", "tool0",
                                 "--com", "0.06,0.02,0.05", "--n-boot", "50", "--out", str(tmp_path / "p.json")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "p.json").read_text())
    assert doc["alignment"][0]["lag_s"] == pytest.approx(-LAG, abs=0.02) and "lag of -1.2" in " ".join(r.output.split())
    assert doc["mass"] == pytest.approx(4.0, rel=0.03), doc["mass"]


def test_payload_heavier_than_the_robot_is_refused_unless_accepted(shifted_pair, tmp_path):
    """Currents read with gains 20× too large: an 80 kg 'payload' on a 33 kg arm is refused, naming the mass."""
    d, robot, K = shifted_pair
    good, bad = tmp_path / "K.json", tmp_path / "K20.json"
    good.write_text(json.dumps(dict(zip(robot.actuated_joints, map(float, K)))))
    bad.write_text(json.dumps(dict(zip(robot.actuated_joints, map(float, 20 * K)))))
    common = ["--robot", "ur10", "--columns", COLS, "--savgol-window", "21", "--trim", "1.5:-1"]
    r = CliRunner().invoke(app, ["identify", *common, "--data", str(d / "u.csv"), "--gains", str(good),
                                 "--method", "ols", "--no-plot", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    args = ["payload", *common, "--model", str(tmp_path / "m"), "--data", str(d / "l.csv"), "--no-load",
            str(d / "u.csv"), "--align", "time", "--frame", "tool0", "--com", "0.06,0.02,0.05", "--n-boot", "20",
            "--gains", str(bad)]
    r = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "p.json")])
    out = " ".join(r.output.split())
    assert r.exit_code == 2 and "more than the whole robot model" in out and "--accept-implausible" in out, out
    assert not (tmp_path / "p.json").exists()
    r = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "p.json"), "--accept-implausible"])
    assert r.exit_code == 0, r.output

"""A model applied to another robot is refused in one line naming both robots (issue 42).

A model identified on a UR10 used with ``--robot ur5`` (the same joint names, other link lengths) ran
on the wrong kinematics, exit 0. The model folder stores its robot's kinematic tree
(``robot.kinematics``: names, types, parents, placements, and a fingerprint); every command applying a
model compares it with the robot given. Models written before it (no ``kinematics``) still load with
their robot, and another robot gets one short line instead of a list of "did you mean" hints.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.export import write_urdf
from sensorless.robot import kinematics_difference, kinematics_fingerprint, kinematics_table, load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory


def _run(args):
    r = CliRunner().invoke(app, [str(a) for a in args])
    return r.exit_code, " ".join(r.output.split())


@pytest.fixture(scope="module")
def ur10_model(tmp_path_factory):
    """A UR10 log and its OLS model (identified by the CLI), and a UR5 log of the same joints."""
    d = tmp_path_factory.mktemp("ur10")
    for name in ("ur10", "ur5"):
        robot = load_robot(name)
        log = synthetic_trajectory(perturbed_truth(robot, rng=0), random_fourier(robot, rng=1).sample(100, 6.0),
                                   noise_std=0.05, rng=2)
        write_npz(log, d / f"{name}.npz")
    code, out = _run(["identify", "--robot", "ur10", "--data", d / "ur10.npz", "--method", "ols", "--no-plot",
                      "--out", d / "m"])
    assert code == 0, out
    return d


COMMANDS = {
    "predict": ["predict", "--out", "p.npz"],
    "monitor": ["monitor", "--out", "mon"],
    "estimate-force": ["estimate-force", "--frame", "tool0", "--out", "f.npz"],
    "payload": ["payload", "--frame", "tool0", "--n-boot", "0", "--out", "pay.json"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_ur10_model_with_the_ur5_is_refused_naming_both(ur10_model, tmp_path, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    name, *rest = COMMANDS[command]
    code, out = _run([name, "--robot", "ur5", "--model", ur10_model / "m", "--data", ur10_model / "ur5.npz", *rest])
    assert code == 2, out
    assert "identified on robot 'ur10'" in out and "the robot given, 'ur5'" in out, out
    assert "shoulder_pan_joint' is 0.0381 m from its place" in out, out  # the UR10's base is 38 mm higher
    assert "--robot" in out and len(out) < 400 and "Traceback" not in out, out
    assert not list(tmp_path.iterdir())  # nothing written


def test_the_same_robot_is_accepted_and_the_fingerprint_is_stored(ur10_model, tmp_path):
    doc = json.loads((ur10_model / "m" / "result.json").read_text())
    stored = doc["robot"]["kinematics"]
    assert stored["fingerprint"] == kinematics_fingerprint(kinematics_table(load_robot("ur10").model))
    code, out = _run(["predict", "--robot", "ur10", "--model", ur10_model / "m", "--data", ur10_model / "ur10.npz",
                      "--out", tmp_path / "p.npz"])
    assert code == 0, out


def test_a_model_without_kinematics_loads_and_another_robot_gets_one_short_line(ur10_model, tmp_path):
    doc = json.loads((ur10_model / "m" / "result.json").read_text())
    del doc["robot"]["kinematics"]  # a model written before the fingerprint
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "result.json").write_text(json.dumps(doc))
    code, out = _run(["predict", "--robot", "ur10", "--model", tmp_path / "old", "--data", ur10_model / "ur10.npz",
                      "--out", tmp_path / "p.npz"])
    assert code == 0, out
    code, out = _run(["predict", "--robot", "panda", "--model", tmp_path / "old", "--data", ur10_model / "ur10.npz",
                      "--out", tmp_path / "q.npz"])
    assert code == 2 and "identified on robot 'ur10'" in out and "'panda'" in out, out
    assert "did you mean" not in out and len(out) < 300, out


def test_the_robots_exported_urdf_is_the_same_robot(tmp_path):
    """Printed precision is not another robot: the tree re-read from the URDF the tool writes matches."""
    robot = load_robot("ur5")
    path = write_urdf(robot, robot.inertial_parameters(), tmp_path / "ur5.urdf")
    again = load_robot(str(path))
    assert kinematics_difference(kinematics_table(robot.model), kinematics_table(again.model)) is None


def test_each_kind_of_difference_is_named():
    base = kinematics_table(load_robot("ur5").model)

    def changed(row, col, value):
        t = [list(r) for r in base]
        t[row][col] = value
        return t

    assert "is RX in the robot given, RZ in the model's" in kinematics_difference(base, changed(0, 1, "JointModelRX"))
    assert "hangs from 'elbow_joint'" in kinematics_difference(base, changed(4, 2, "elbow_joint"))
    assert "turned" in kinematics_difference(base, changed(2, 6, base[2][6] - 0.1))
    assert "'elbow_joint' is 0.01 m" in kinematics_difference(base, changed(2, 5, base[2][5] + 0.01))
    assert kinematics_difference(base, changed(2, 5, base[2][5] + 1e-7)) is None  # printed precision
    assert "has no joint(s) ['wrist_3_joint']" in kinematics_difference(base, base[:-1])
    assert "has joint(s) ['wrist_3_joint'] the model's has not" in kinematics_difference(base[:-1], base)
    assert np.isclose(base[2][5], 0.425)

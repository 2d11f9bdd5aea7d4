"""Wrenches logged in a model frame (issue 27, item 2 "Formats"): ``--wrench-frame`` expresses sole and
F/T-sensor wrenches in world axes at the contact frames with the logged kinematics, so a log written
in those frames identifies and predicts like the world-frame log. The regression case: a humanoid
walking log with sole wrenches that had to be rotated to world by hand."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.data.wrench_frames import express_wrenches, wrench_frame_map
from sensorless.errors import DataError, OptionError, RobotModelError
from sensorless.robot import add_frame, load_robot
from sensorless.testing import perturbed_truth
from sensorless_studies.simulation.wrench_log import walking_flags, wrench_log

FEET = ("left_sole_link", "right_sole_link")
#: an F/T sensor above the left sole, tilted and turned (name:parent:xyz:rpy, as --add-frame takes it)
FT = ("left_ft", "leg_left_6_link", (0.02, -0.01, -0.05), (0.3, -0.2, 1.2))


@pytest.fixture(scope="module")
def legs():
    robot = load_robot("talos_legs")
    add_frame(robot, *FT)
    return robot


@pytest.fixture(scope="module")
def world_log(legs):
    """Alternating double/single support, wrenches in world axes at the soles, no contact flags
    (contacts are inferred from the normal forces, which must be world-vertical for that)."""
    lg = wrench_log(perturbed_truth(legs, rng=3).robot, FEET, duration=6.0, flags=walking_flags(600, 2, 80), seed=1)
    return lg.with_(extras={"contact_forces": lg.extras["contact_forces"]})


def in_frames(robot, traj, frames):
    """Oracle: the world-aligned wrench at each sole, moved to the world origin and then into the
    LOCAL frame ``frames[k]`` by Pinocchio's SE3 actions on forces (not the module's formula)."""
    model, data = robot.model, robot.data
    Q = robot.full_configuration(traj.q, traj.base_q)
    w = traj.extras["contact_forces"]
    out = w.copy()
    for i in range(len(traj)):
        pin.framesForwardKinematics(model, data, Q[i])
        for k, (c, s) in enumerate(zip(FEET, frames)):
            at_origin = pin.SE3(np.eye(3), data.oMf[model.getFrameId(c)].translation).act(pin.Force(w[i, k]))
            out[i, k] = data.oMf[model.getFrameId(s)].actInv(at_origin).vector
    return traj.with_(extras={**traj.extras, "contact_forces": out})


def test_express_wrenches_inverts_the_frame_change(legs, world_log):
    frames = ("left_ft", "right_sole_link")
    logged = in_frames(legs, world_log, frames)
    assert np.abs(logged.extras["contact_forces"] - world_log.extras["contact_forces"]).max() > 10  # really moved
    back = express_wrenches(logged, legs, dict(zip(FEET, frames)))
    np.testing.assert_allclose(back.extras["contact_forces"], world_log.extras["contact_forces"], atol=1e-8)
    assert back.provenance["wrench_frames"] == dict(zip(FEET, frames))
    # point contacts (3 columns) rotate the force only; a flattened (N, n·3) array is read too
    forces = world_log.extras["contact_forces"][:, :, :3]
    flat = in_frames(legs, world_log, frames).extras["contact_forces"][:, :, :3].reshape(len(world_log), 6)
    pt = express_wrenches(world_log.with_(extras={"contact_forces": flat}), legs, dict(zip(FEET, frames)))
    np.testing.assert_allclose(pt.extras["contact_forces"], forces, atol=1e-8)


def test_frame_map_and_its_errors(legs, world_log):
    assert wrench_frame_map("contact", FEET, legs) == dict(zip(FEET, FEET))
    assert wrench_frame_map(["left_ft", "world"], FEET, legs) == {"left_sole_link": "left_ft", "right_sole_link": "world"}
    assert wrench_frame_map(None, FEET) is None
    world = wrench_frame_map("world", FEET, legs)
    assert world == dict.fromkeys(FEET, "world")
    # world-aligned wrench topics of a ROS bag ('wrench') become the contact wrenches unchanged
    bag = world_log.with_(base_q=None, extras={"wrench": world_log.extras["contact_forces"]})
    np.testing.assert_array_equal(express_wrenches(bag, legs, world).extras["contact_forces"],
                                  world_log.extras["contact_forces"])
    with pytest.raises(RobotModelError, match="did you mean 'left_sole_link'") as unknown:
        wrench_frame_map("left_sole_lnk,contact", FEET, legs)
    assert "(in Python: sensorless.robot.frame_table(robot) lists them)" in str(unknown.value)  # the CLI: the command
    with pytest.raises(OptionError, match="gives 1 frame"):
        wrench_frame_map("left_ft", FEET, legs)
    with pytest.raises(OptionError, match="`contact_frames`"):
        wrench_frame_map("contact", (), legs)
    with pytest.raises(DataError, match="no base pose"):
        express_wrenches(world_log.with_(base_q=None), legs, dict(zip(FEET, FEET)))
    with pytest.raises(DataError, match="no measured wrenches"):
        express_wrenches(world_log.with_(extras={}), legs, dict(zip(FEET, FEET)))


def test_frames_are_changed_before_the_lowpass(legs, world_log):
    """prepare(): the sensor-frame log, expressed and low-passed, is the world log low-passed."""
    from sensorless.data import prepare

    frames = dict(zip(FEET, ("left_ft", "right_sole_link")))
    got = prepare(in_frames(legs, world_log, tuple(frames.values())), lowpass=20.0, robot=legs, wrench_frames=frames)
    ref = prepare(world_log, lowpass=20.0)
    np.testing.assert_allclose(got.extras["contact_forces"], ref.extras["contact_forces"], atol=1e-7)
    assert "contact_forces" in got.provenance["lowpass"]["channels"]


def _identify(path, out, *extra):
    args = ["identify", "--robot", "talos_legs", "--data", str(path), "--out", str(out), "--contact-frames",
            ",".join(FEET), "--contact-dims", "6,6", "--contact-mode", "wrench", "--joint-terms", "", "--method", "ols",
            "--no-plot", "--urdf-values", "regularised", "--accept-implausible", "--accept-implausible-torques", *extra]  # a short log: equality is the point
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    return json.loads((out / "result.json").read_text())


def test_cli_sensor_frame_log_identifies_and_predicts_like_the_world_log(legs, world_log, tmp_path):
    """Left wrench at the ankle link (10.7 cm above the sole: moments move), right one in its sole's own axes."""
    world = write_npz(world_log, tmp_path / "world.npz")
    sensor = write_npz(in_frames(legs, world_log, ("leg_left_6_link", "right_sole_link")), tmp_path / "sensor.npz")
    ref = _identify(world, tmp_path / "w")
    got = _identify(sensor, tmp_path / "s", "--wrench-frame", "leg_left_6_link,contact")
    p_ref, p_got = np.array(list(ref["parameters"].values())), np.array(list(got["parameters"].values()))
    assert np.abs(p_got - p_ref).max() <= 1e-7 * np.abs(p_ref).max()
    assert got["mass_properties"]["total_mass"] == pytest.approx(ref["mass_properties"]["total_mass"], rel=1e-9)
    assert got["settings"]["preprocessing"]["wrench_frames"] == {"left_sole_link": "leg_left_6_link",
                                                                  "right_sole_link": "right_sole_link"}
    assert ref["settings"]["preprocessing"]["wrench_frames"] is None
    # without the option the sensor-frame log gives another model (the test can fail)
    raw = _identify(sensor, tmp_path / "r")
    assert abs(raw["mass_properties"]["total_mass"] - ref["mass_properties"]["total_mass"]) > 0.5
    # predict reuses the model's wrench frames (the log's wrenches are read, and expressed, on the way)
    preds = []
    for model, log, name in ((tmp_path / "w", world, "pw.npz"), (tmp_path / "s", sensor, "ps.npz")):
        res = CliRunner().invoke(app, ["predict", "--robot", "talos_legs", "--floating-base", "--model", str(model),
                                       "--data", str(log), "--out", str(tmp_path / name)])
        assert res.exit_code == 0, res.output
        preds.append(np.load(tmp_path / name))
    assert json.loads(str(preds[1]["preprocessing"]))["wrench_frames"] == got["settings"]["preprocessing"]["wrench_frames"]
    np.testing.assert_allclose(preds[1]["tau_pred"], preds[0]["tau_pred"], atol=1e-6)


def test_cli_added_sensor_frame_and_errors(legs, world_log, tmp_path):
    """An F/T frame declared with --add-frame; an unknown frame is refused with the closest names,
    before any output is written."""
    sensor = write_npz(in_frames(legs, world_log, ("left_ft", "right_sole_link")), tmp_path / "ft.npz")
    ref = _identify(write_npz(world_log, tmp_path / "world.npz"), tmp_path / "w")
    spec = f"{FT[0]}:{FT[1]}:{','.join(map(str, FT[2]))}:{','.join(map(str, FT[3]))}"
    got = _identify(sensor, tmp_path / "a", "--add-frame", spec, "--wrench-frame", "left_ft", "--wrench-frame",
                    "right_sole_link")
    assert got["mass_properties"]["total_mass"] == pytest.approx(ref["mass_properties"]["total_mass"], rel=1e-9)
    base = ["identify", "--robot", "talos_legs", "--data", str(sensor), "--contact-frames", ",".join(FEET),
            "--contact-dims", "6,6", "--joint-terms", "", "--method", "ols", "--out", str(tmp_path / "bad")]
    res = CliRunner().invoke(app, base + ["--contact-mode", "wrench", "--wrench-frame", "left_sole_lnk,contact"])
    assert res.exit_code == 2 and "did you mean 'left_sole_link'" in res.output and not (tmp_path / "bad").exists()
    flat = " ".join(res.output.split())
    assert "(`sensorless frames --robot ...` lists its" in flat and "in Python" not in flat
    res = CliRunner().invoke(app, base + ["--contact-mode", "wrench", "--wrench-frame", "left_ft"])
    assert res.exit_code == 2 and "one per contact frame" in res.output
    res = CliRunner().invoke(app, base + ["--wrench-frame", "contact"])
    assert res.exit_code == 2 and "--contact-mode wrench" in res.output

"""`sensorless frames` and `--add-frame` (issue 23, item 4): every frame with its parent, origin
and axes; a frame added at a known location on a URDF, an example-robot-data model and the
dVRK PSM (a coordinate robot), usable wherever a frame is taken."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from test_cli_psm import COLS, _run
from test_identification_payload_determinacy import COM, M, case, psm_cli  # noqa: F401  (fixtures)

from sensorless.errors import RobotModelError
from sensorless.robot import add_frame, frame_table, load_robot
from sensorless.robots.dvrk_psm import psm_robot


def test_frames_lists_every_frame_with_parent_origin_and_axes(tmp_path):
    code, out = _run(["frames", "--robot", "dvrk_psm", "--out", tmp_path / "f.json"])
    assert code == 0, out
    rows = json.loads((tmp_path / "f.json").read_text())["frames"]
    r = psm_robot()
    assert [x["name"] for x in rows] == [f.name for f in r.tree.model.frames]
    rcm = next(x for x in rows if x["name"] == "rcm")
    assert rcm["parent_joint"] == "pitch_bottom" and "rcm" in out and "tool_tip" in out
    data = r.tree.model.createData()
    pin.framesForwardKinematics(r.tree.model, data, r.tree_state(np.zeros((1, 7)))[0][0])
    M_ = data.oMf[r.frame_id("rcm")]
    np.testing.assert_allclose(rcm["world_origin"], M_.translation, atol=1e-12)
    np.testing.assert_allclose(np.array(rcm["world_axes"]).T, M_.rotation, atol=1e-12)


@pytest.mark.parametrize("spec", ["panda", "urdf"])
def test_add_frame_on_urdf_and_example_robot_data(tmp_path, spec):
    base = load_robot("panda")
    robot = base.urdf_path if spec == "urdf" else "panda"
    code, out = _run(["frames", "--robot", robot, "--add-frame", "tcp:panda_hand:0,0,0.1:0,0,1.5707963267948966",
                      "--out", tmp_path / "f.json"])
    assert code == 0, out
    tcp = json.loads((tmp_path / "f.json").read_text())["frames"][-1]
    assert tcp["name"] == "tcp" and tcp["parent_frame"] == "panda_hand" and tcp["type"] == "OP_FRAME"
    data = base.model.createData()
    pin.framesForwardKinematics(base.model, data, base.full_configuration(np.zeros((1, base.n_actuated)))[0])
    want = data.oMf[base.frame_id("panda_hand")] * pin.SE3(pin.rpy.rpyToMatrix(0, 0, np.pi / 2), np.array([0, 0, 0.1]))
    np.testing.assert_allclose(tcp["world_origin"], want.translation, atol=1e-9)
    np.testing.assert_allclose(np.array(tcp["world_axes"]).T, want.rotation, atol=1e-9)


def test_add_frame_validation_names_the_frame_and_parent():
    r = psm_robot()
    fid = add_frame(r, "probe", "tool_tip", [0, 0, 0.01])
    assert r.frame_id("probe") == fid and r.data.oMf.__len__() == r.model.nframes  # data recreated
    assert frame_table(r)[-1]["name"] == "probe"
    with pytest.raises(RobotModelError, match="unknown parent frame 'nope'"):
        add_frame(r, "x", "nope", [0, 0, 0])
    with pytest.raises(RobotModelError, match="'probe': the model already has"):
        add_frame(r, "probe", "tool_tip", [0, 0, 0])
    with pytest.raises(RobotModelError, match="finite"):
        add_frame(r, "y", "tool_tip", [0, np.nan, 0])
    code, out = _run(["frames", "--robot", "dvrk_psm", "--add-frame", "a:tool_tip:0,0"])
    assert code == 2 and "--add-frame 'a:tool_tip:0,0'" in out
    code, out = _run(["frames", "--robot", "dvrk_psm", "--add-frame", "a:nope:0,0,0"])
    assert code == 2 and "unknown parent frame 'nope'" in out


def test_every_frame_command_takes_add_frame():
    for cmd in ("payload", "estimate-force", "monitor", "identify", "frames"):
        code, out = _run([cmd, "--help"])
        assert code == 0 and "--add-frame" in out, cmd


def test_payload_at_an_added_frame_on_the_psm(psm_cli):  # noqa: F811
    """The payload of test_identification_payload_determinacy sits at COM in 'rcm', whose origin is fixed (m
    undetermined). A frame added at the payload's location moves: m is determined there."""
    d = psm_cli
    base = ["payload", "--robot", "dvrk_psm", "--model", d / "model", *COLS, "--n-boot", "0", "--data", d / "rcm.csv"]
    code, out = _run(base + ["--add-frame", "at_rcm:rcm:0,0,0", "--frame", "at_rcm", "--out", d / "x.json"])
    assert code == 2 and "--com" in out, out
    held = ["--add-frame", f"held:rcm:{','.join(map(str, COM))}", "--frame", "held"]
    code, out = _run(base + held + ["--mode", "mass", "--out", d / "y.json"])  # the payload at the frame's origin
    assert code == 0, out
    doc = json.loads((d / "y.json").read_text())
    assert abs(doc["mass"] - M) / M < 0.03, doc["mass"]
    # 'held' only rotates about the RCM: with its CoM free too, m and m·c are told apart by
    # accelerations alone (a lever of ~1 mm), so m is refused, naming --com
    code, out = _run(base + held + ["--mode", "com", "--out", d / "z.json"])
    assert code == 2 and "--com" in out and "rotates" in out, out

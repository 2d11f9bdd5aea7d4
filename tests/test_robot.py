"""Robot loading: URDF, MJCF, example-robot-data; names, armature, clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorless.errors import JointNameError, RobotModelError
from sensorless.robot import load_robot

MJCF = """<mujoco model="two_link">
  <worldbody>
    <body name="link1" pos="0 0 0.1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-2 2" armature="0.05"/>
      <inertial pos="0.1 0 0" mass="1.5" diaginertia="0.01 0.02 0.02"/>
      <body name="link2" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 1 0" range="-1.5 1.5" armature="0.02"/>
        <inertial pos="0.15 0 0" mass="0.8" diaginertia="0.005 0.01 0.01"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjcf_loads_with_joint_names_and_armature(tmp_path):
    path = tmp_path / "two_link.xml"
    path.write_text(MJCF)
    r = load_robot(path)
    assert r.joint_names == ("j1", "j2")
    assert not r.floating_base
    np.testing.assert_allclose(r.armature, [0.05, 0.02])
    assert abs(r.summary()["total_mass"] - 2.3) < 1e-12


def test_example_robot_data_and_floating_base(solo12, panda):
    assert solo12.floating_base and solo12.nv == 18 and len(solo12.actuated_joints) == 12
    assert panda.nv == 7 and panda.joint_names[0] == "panda_joint1"
    S = solo12.selection
    assert S.shape == (12, 18) and np.all(S[:, :6] == 0)


def test_urdf_floating_base_option(kuka):
    r = load_robot(kuka.source, floating_base=True)
    assert r.floating_base and r.nv == 13


def test_armature_override_and_locking(panda):
    r = load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"], armature={"panda_joint3": 0.1})
    assert r.armature[2] == 0.1


def test_clear_errors(panda, tmp_path):
    with pytest.raises(RobotModelError, match="unknown joint 'elbow'"):
        panda.joint_id("elbow")
    with pytest.raises(RobotModelError, match="unknown frame 'tool0'"):
        panda.frame_id("tool0")
    with pytest.raises(JointNameError, match="wrist"):
        load_robot("panda", actuated_joints=["wrist"])
    with pytest.raises(RobotModelError, match="cannot lock"):
        load_robot("panda", lock_joints=["nope"])
    with pytest.raises(RobotModelError, match="no such"):
        load_robot(tmp_path / "missing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'>")
    with pytest.raises(RobotModelError, match="bad.urdf"):
        load_robot(bad)


def test_with_inertial_parameters_round_trip(panda):
    pi = panda.inertial_parameters()
    r2 = panda.with_inertial_parameters(pi * 1.1)
    np.testing.assert_allclose(r2.inertial_parameters(), pi * 1.1)
    with pytest.raises(RobotModelError):
        panda.with_inertial_parameters(pi[:-1])


XACRO = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="two">
  <xacro:property name="m1" value="2.0"/>
  <xacro:macro name="lnk" params="name mass z">
    <link name="${name}"><inertial><origin xyz="0 0 ${z}"/><mass value="${mass}"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.005"/></inertial></link>
  </xacro:macro>
  <link name="base"/>
  <xacro:lnk name="l1" mass="${m1}" z="0.2"/>
  <xacro:lnk name="l2" mass="${m1 / 2}" z="0.15"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="50" velocity="3"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="50" velocity="3"/></joint>
</robot>
"""


def test_xacro_file_loads_like_its_expanded_urdf(tmp_path, monkeypatch):
    pytest.importorskip("xacro")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    (tmp_path / "arm.urdf.xacro").write_text(XACRO)
    r = load_robot(tmp_path / "arm.urdf.xacro", trust_xacro=True)
    assert r.joint_names == ("j1", "j2") and r.name == "arm" and r.source.endswith("arm.urdf.xacro")
    assert [r.model.inertias[k].mass for k in (1, 2)] == [2.0, 1.0]  # macros and expressions expanded
    assert Path(r.urdf_path).parent == tmp_path / "cache" / "sensorless" / "xacro"
    plain = load_robot(r.urdf_path)
    for a, b in zip(r.model.inertias, plain.model.inertias):
        np.testing.assert_array_equal(a.toDynamicParameters(), b.toDynamicParameters())
    assert load_robot(tmp_path / "arm.urdf.xacro", trust_xacro=True).urdf_path == r.urdf_path  # cached by content


def test_xacro_that_needs_ros_says_how_to_expand_it(tmp_path, monkeypatch):
    pytest.importorskip("xacro")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bad = tmp_path / "bad.xacro"
    bad.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="x">'
                   '<xacro:include filename="$(find no_such_pkg)/a.xacro"/></robot>')
    with pytest.raises(RobotModelError, match=r"bad.xacro: xacro could not expand it .*xacro .*bad.xacro > robot.urdf"):
        load_robot(bad, trust_xacro=True)


def test_a_misspelt_robot_name_gets_the_close_names_on_the_cli():
    """Issue 24: an unknown robot name is answered with "did you mean" (difflib), in one line, exit 2."""
    from typer.testing import CliRunner

    from sensorless.cli import app

    with pytest.raises(RobotModelError, match=r"did you mean 'ur5'"):
        load_robot("ur55")
    with pytest.raises(RobotModelError, match=r"did you mean 'panda'"):
        load_robot("Panda")
    with pytest.raises(RobotModelError) as exc:
        load_robot("qwertyuiop")
    assert "did you mean" not in str(exc.value) and "dvrk_psm" in str(exc.value)
    res = CliRunner().invoke(app, ["identify", "--robot", "solo13", "--data", "x.npz", "--out", "o"])
    assert res.exit_code == 2 and "did you mean 'solo12'" in res.output and "Traceback" not in res.output

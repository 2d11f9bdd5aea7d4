"""MJCF export (issue 42): MuJoCo's inverse dynamics on the exported model is the tool's rigid-body +
armature + viscous prediction (to 1e-6 relative), the friction terms MuJoCo cannot hold are named in
the header, each value carries its verdict, and a robot read from MJCF keeps its file's structure."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import read_trajectory, savgol_derivatives, write_npz
from sensorless.excitation import random_fourier
from sensorless.errors import PhysicalConsistencyError
from sensorless.export_mjcf import write_mjcf
from sensorless.identification.artifact import load_model_folder
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory

mujoco = pytest.importorskip("mujoco")

TWO_LINK = """<mujoco model="two_link">
  <compiler angle="radian" inertiafromgeom="true"/>
  <default><joint damping="0.05"/></default>
  <worldbody>
    <light pos="0 0 3"/>
    <body name="upper" pos="0 0 0.5">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-2 2"/>
      <geom name="upper_geom" type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="2.0"/>
      <body name="lower" pos="0.4 0 0" euler="0 0.3 0">
        <joint name="elbow" type="hinge" axis="0 1 0" pos="0.02 0 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.0"/>
        <body name="tool" pos="0.3 0 0">
          <geom type="sphere" size="0.05" mass="0.5"/>
          <site name="tip" pos="0.05 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="m1" joint="shoulder" gear="50"/><motor name="m2" joint="elbow" gear="30"/></actuator>
</mujoco>
"""


def _mujoco_inverse(path, q, v, a) -> np.ndarray:
    """qfrc_inverse per sample, MuJoCo's dry friction (a constraint) off: the smooth part of the model."""
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    d = mujoco.MjData(m)
    out = np.empty_like(q)
    for i in range(len(q)):
        d.qpos[:], d.qvel[:], d.qacc[:] = q[i], v[i], a[i]
        mujoco.mj_inverse(m, d)
        out[i] = d.qfrc_inverse
    return out


def _relative(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_mujoco_inverse_dynamics_on_the_export_is_the_tools_prediction(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ur5 = load_robot("ur5")
    log = synthetic_trajectory(perturbed_truth(ur5, rng=0), random_fourier(ur5, rng=1).sample(100.0, 6.0),
                               noise_std=0.05, rng=2)
    write_npz(log, "log.npz")
    run = CliRunner().invoke
    r = run(app, ["identify", "--robot", "ur5", "--data", "log.npz", "--joint-terms", "fv,fc,offset,armature",
                  "--gamma", "1e-3", "--no-plot", "--out", "m"])
    assert r.exit_code == 0, r.output
    r = run(app, ["export", "--robot", "ur5", "--model", "m", "--mjcf", "ur5.xml"])
    assert r.exit_code == 0, r.output
    art = load_model_folder("m", ur5)
    s, p = art.structure, art.parameters.copy()
    for j in s.robot.term_joints:  # the tool's rigid-body + armature + viscous part
        for t in s.terms_of(j):
            if t not in ("fv", "armature"):
                p[s.joint_term_index(j, t)] = 0.0
    traj = savgol_derivatives(read_trajectory("log.npz", robot=ur5))
    tool = s.torques(p, traj)
    err = _relative(_mujoco_inverse("ur5.xml", traj.q, traj.v, traj.a), tool)
    assert err < 1e-6, err
    text = (tmp_path / "ur5.xml").read_text()
    header = text.split("-->")[0]
    assert "NOT in this file" in header and "offset = " in header and "coulomb_smoothing" in header
    assert "frictionloss = Coulomb friction fc" in header
    assert text.count("mass: ") == 6 and "fv: data" in text  # each body's and joint's verdicts
    m = mujoco.MjModel.from_xml_path("ur5.xml")
    fc = [p2 for p2 in art.parameters[[s.joint_term_index(j, "fc") for j in s.robot.term_joints]]]
    np.testing.assert_allclose(m.dof_frictionloss, fc, rtol=1e-9)
    r = run(app, ["export", "--robot", "ur5", "--model", "m", "--mjcf", "ur5.xml"])
    assert r.exit_code == 2 and "--force" in r.output  # an existing file is kept


def test_a_robot_read_from_mjcf_keeps_its_files_structure(tmp_path):
    src = tmp_path / "arm.xml"
    src.write_text(TWO_LINK)
    robot = load_robot(str(src))
    truth = perturbed_truth(robot, rng=3).robot
    terms = {"shoulder": {"fv": 0.4, "fc": 0.9, "armature": 0.02, "offset": 0.1},
             "elbow": {"fv": 0.2, "fc": 0.5, "armature": 0.01, "stribeck": 0.3}}
    out = write_mjcf(robot, truth.inertial_parameters(), tmp_path / "out.xml", terms)
    root = ET.parse(out).getroot()
    assert [a.get("name") for a in root.iter("motor")] == ["m1", "m2"]
    assert [s.get("name") for s in root.iter("site")] == ["tip"] and len(list(root.iter("geom"))) == 3
    assert root.find("default/joint").get("damping") == "0.05" and root.find("compiler").get("inertiafromgeom") == "auto"
    tool = next(b for b in root.iter("body") if b.get("name") == "tool")
    assert tool.find("inertial").get("mass") == "0"  # welded: its mass is in the identified inertial of 'lower'
    header = out.read_text().split("-->")[0]
    assert "shoulder: offset = 0.1" in header and "elbow: stribeck = 0.3" in header
    t = np.linspace(0, 2, 60)
    q = np.column_stack([0.8 * np.sin(2 * t), 0.5 * np.cos(3 * t)])
    v = np.column_stack([1.6 * np.cos(2 * t), -1.5 * np.sin(3 * t)])
    a = np.column_stack([-3.2 * np.sin(2 * t), -4.5 * np.cos(3 * t)])
    data = truth.model.createData()
    tool_tau = np.array([pin.rnea(truth.model, data, q[i], v[i], a[i]) for i in range(len(t))])
    tool_tau += a * [0.02, 0.01] + v * [0.4, 0.2]
    assert _relative(_mujoco_inverse(out, q, v, a), tool_tau) < 1e-6


def test_a_body_of_negative_mass_is_refused(tmp_path):
    ur5 = load_robot("ur5")
    pi = ur5.inertial_parameters().copy()
    pi[10] = -1.0
    with pytest.raises(PhysicalConsistencyError, match=r"'shoulder_lift_joint'\] have mass ≤ 0 .*\(lmi"):
        write_mjcf(ur5, pi, tmp_path / "x.xml")
    assert not (tmp_path / "x.xml").exists()

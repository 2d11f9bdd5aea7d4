from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import PhysicalConsistencyError, RobotModelError
from sensorless.export import read_joint_terms, write_joint_terms, write_urdf
from sensorless.parameters import JointTerms, com_frame, from_com_frame, is_physically_consistent
from sensorless.robot import Robot, load_robot

KUKA = Path("/work/shared/realdata/kuka_lwr4_flobaroid/model/kuka_lwr4.urdf")

ROBOTS = {
    "panda": ("panda", {"lock_joints": ["panda_finger_joint1", "panda_finger_joint2"]}),
    "ur5": ("ur5", {}),
    "kuka": (str(KUKA), {}),
    "solo12": ("solo12", {}),
}


def perturb(pi: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Consistent but different: scale masses, shift CoMs, rotate CoM inertias slightly."""
    m, c, I_c = com_frame(pi.reshape(-1, 10))
    n = len(m)
    s = rng.uniform(0.8, 1.2, n)
    R = np.array([pin.exp3(0.1 * rng.standard_normal(3)) for _ in range(n)])
    I_new = s[:, None, None] * R @ I_c @ np.swapaxes(R, 1, 2)
    out = from_com_frame(s * m, c + 0.01 * rng.standard_normal((n, 3)), I_new).ravel()
    assert is_physically_consistent(out)
    assert np.abs(out - pi).max() > 1e-3
    return out


def compare_rnea(ref: Robot, other: Robot, rng: np.random.Generator, n: int = 5) -> None:
    """pin.rnea of both models agree on random states (joints matched by name)."""
    assert set(ref.joint_names) == set(other.joint_names)
    assert ref.floating_base == other.floating_base
    perm = other.joint_order(ref.joint_names)  # ref order -> other order
    for _ in range(n):
        qj, vj, aj = rng.uniform(-1.5, 1.5, (3, len(ref.joint_names)))
        base_q = base_v = base_a = None
        if ref.floating_base:
            base_q = np.r_[rng.standard_normal(3), pin.Quaternion(pin.exp3(rng.standard_normal(3))).coeffs()]
            base_v, base_a = rng.standard_normal((2, 6))
        q1 = ref.full_configuration(qj, base_q)[0]
        v1, a1 = ref.full_velocity(vj, base_v)[0], ref.full_velocity(aj, base_a)[0]
        q2 = other.full_configuration(qj[perm], base_q)[0]
        v2, a2 = other.full_velocity(vj[perm], base_v)[0], other.full_velocity(aj[perm], base_a)[0]
        tau1 = pin.rnea(ref.model, ref.data, q1, v1, a1).copy()
        tau2 = pin.rnea(other.model, other.data, q2, v2, a2).copy()
        if ref.floating_base:
            np.testing.assert_allclose(tau2[:6], tau1[:6], atol=1e-9, rtol=0)
        for name in ref.joint_names:
            assert tau2[other.v_index(name)] == pytest.approx(tau1[ref.v_index(name)], abs=1e-9, rel=0)


@pytest.mark.parametrize("key", list(ROBOTS))
def test_written_urdf_reproduces_dynamics(key, tmp_path):
    spec, kw = ROBOTS[key]
    if key == "kuka" and not KUKA.exists():
        pytest.skip("KUKA LWR4 model not available")
    rng = np.random.default_rng(1)
    robot = load_robot(spec, **kw)
    pi = perturb(robot.inertial_parameters(), rng)
    path = write_urdf(robot, pi, tmp_path / f"{key}.urdf")
    assert [p.name for p in tmp_path.iterdir()] == [f"{key}.urdf"]  # no temp file left
    reloaded = load_robot(path, floating_base=True if robot.floating_base else None)
    assert reloaded.n_bodies == robot.n_bodies
    compare_rnea(robot.with_inertial_parameters(pi), reloaded, rng)
    # body parameters themselves match by joint name
    for k, name in enumerate(robot.body_names):
        j = reloaded.model.getJointId(name) if name in reloaded.model.names else 1
        np.testing.assert_allclose(
            reloaded.model.inertias[j].toDynamicParameters(), pi[10 * k : 10 * k + 10], atol=1e-12
        )
    # links named after the Pinocchio BODY frames
    links = {e.get("name") for e in ET.parse(path).getroot().iter("link")}
    if key == "panda":
        assert {"panda_link0", "panda_link1", "panda_link7"} <= links
    if key == "solo12":
        assert "base_link" in links and "FL_SHOULDER" in links
        assert ET.parse(path).getroot().find("joint[@name='root_joint']") is None


def _synthetic_robot() -> Robot:
    """Every supported 1-DoF joint type, random placements, no BODY frames."""
    model = pin.Model()
    joints = [
        pin.JointModelRX(),
        pin.JointModelRUBY(),
        pin.JointModelPZ(),
        pin.JointModelRevoluteUnaligned(np.array([0.0, 0.6, 0.8])),
        pin.JointModelPrismaticUnaligned(np.array([0.6, 0.0, -0.8])),
        pin.JointModelRUBZ(),
    ]
    parent = 0
    for k, jm in enumerate(joints):
        nq = jm.nq
        jid = model.addJoint(
            parent if k != 3 else 1, jm, pin.SE3.Random(), f"j{k}",
            np.full(1, 10.0), np.full(1, 5.0), np.full(nq, -2.0), np.full(nq, 2.0),
        )
        model.appendBodyToJoint(jid, pin.Inertia(1.0 + k, np.array([0.1, 0.0, -0.1]), np.diag([0.2, 0.3, 0.4])), pin.SE3.Identity())
        parent = jid
    return Robot(model, name="synthetic")


def test_all_joint_types_and_joint_terms(tmp_path):
    rng = np.random.default_rng(2)
    robot = _synthetic_robot()
    pi = perturb(robot.inertial_parameters(), rng)
    jt = JointTerms(robot.joint_names, fv=np.arange(6) * 0.1, fc=np.arange(6) * 0.01 + 0.5, offset=np.ones(6))
    path = write_urdf(robot, pi, tmp_path / "syn.urdf", joint_terms=jt)
    root = ET.parse(path).getroot()
    types = {j.get("name"): j.get("type") for j in root.iter("joint")}
    assert types == {"j0": "revolute", "j1": "continuous", "j2": "prismatic", "j3": "revolute",
                     "j4": "prismatic", "j5": "continuous"}
    assert root.find("link[@name='j0_link']") is not None and root.find("link[@name='base_link']") is not None
    reloaded = load_robot(path)
    for name in robot.joint_names:
        j1, j2 = robot.model.getJointId(name), reloaded.model.getJointId(name)
        assert robot.model.joints[j1].nq == reloaded.model.joints[j2].nq
        iv = reloaded.v_index(name)
        k = robot.joint_names.index(name)
        assert reloaded.model.damping[iv] == pytest.approx(jt.fv[k])
        assert reloaded.model.friction[iv] == pytest.approx(jt.fc[k])
        if not robot.is_continuous(name):
            assert reloaded.model.upperPositionLimit[reloaded.q_index(name)] == pytest.approx(2.0)
        assert reloaded.model.effortLimit[iv] == pytest.approx(10.0)
    compare_rnea(robot.with_inertial_parameters(pi), reloaded, rng)


def test_operational_frames_are_kept_with_frames_true(tmp_path):
    """The RCM arm's tool_tip and shaft_tip (OP frames added in code) reload at the same pose."""
    from sensorless_studies.simulation.surgical_arm import build_surgical_arm

    robot = build_surgical_arm(armature=False)  # URDF has no rotor inertia
    pi = robot.inertial_parameters()
    assert "tool_tip" not in {f.name for f in load_robot(write_urdf(robot, pi, tmp_path / "a.urdf")).model.frames}
    reloaded = load_robot(write_urdf(robot, pi, tmp_path / "b.urdf", frames=True))
    assert reloaded.n_bodies == robot.n_bodies
    rng = np.random.default_rng(4)
    for _ in range(3):
        q = rng.uniform(-0.5, 0.5, robot.model.nq)
        for r in (robot, reloaded):
            pin.framesForwardKinematics(r.model, r.data, q)
        for name in ("tool_tip", "shaft_tip"):
            a, b = robot.data.oMf[robot.model.getFrameId(name)], reloaded.data.oMf[reloaded.model.getFrameId(name)]
            np.testing.assert_allclose(b.homogeneous, a.homogeneous, atol=1e-12)
    compare_rnea(robot, reloaded, rng)


def test_nonpositive_mass_is_rejected(tmp_path):
    robot = load_robot("ur5")
    pi = robot.inertial_parameters()
    pi[10 * 2] = 0.0
    with pytest.raises(PhysicalConsistencyError, match="elbow_joint"):
        write_urdf(robot, pi, tmp_path / "bad.urdf")
    assert not (tmp_path / "bad.urdf").exists()
    with pytest.raises(RobotModelError, match="60"):
        write_urdf(robot, pi[:-1], tmp_path / "bad.urdf")


def test_joint_terms_json_round_trip(tmp_path):
    jt = JointTerms(("a", "b"), fv=[0.5, 0.25], fc=[1.0, 2.0], offset=[-0.1, 0.1], armature=[0.01, 0.02])
    path = write_joint_terms(jt, tmp_path / "sub" / "terms.json")
    back = read_joint_terms(path)
    assert back.joint_names == jt.joint_names
    for t in ("fv", "fc", "offset", "armature"):
        np.testing.assert_array_equal(getattr(back, t), getattr(jt, t))
    law = JointTerms(("a", "b"), fc=[1.0, 2.0], stribeck=[0.5, 0.0], stribeck_velocity=[0.03, 0.0],
                     coulomb_smoothing=[1e-3, 1e-3])
    d = json.loads(write_joint_terms(law, tmp_path / "law.json").read_text())
    assert d["a"]["stribeck_velocity"] == 0.03 and "stribeck" not in d["b"] and d["b"]["coulomb_smoothing"] == 1e-3
    back = read_joint_terms(tmp_path / "law.json")
    for t in ("stribeck", "stribeck_velocity", "coulomb_smoothing"):
        np.testing.assert_array_equal(getattr(back, t), getattr(law, t))

"""URDF export by patching the source's <inertial> tags: meshes and fixed links survive."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from sensorless.errors import PhysicalConsistencyError
from sensorless.parameters import JointTerms
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth
from sensorless.urdf_patch import export_urdf, patch_urdf_inertials


def _truth_pi(robot, rng):
    """A consistent parameter vector (Pinocchio order) different from the URDF's own."""
    m = perturbed_truth(robot, rng=rng).robot.model
    return np.concatenate([m.inertias[j].toDynamicParameters() for j in range(1, m.njoints)])


def _tags(path):
    root = ET.parse(path).getroot()
    return {t: sorted(ET.tostring(e, encoding="unicode") for e in root.iter(t)) for t in ("visual", "collision")}, root


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_patched_urdf_keeps_meshes_and_reloads_identified(name, tmp_path):
    robot = load_robot(name)
    pi = _truth_pi(robot, 3)
    out = patch_urdf_inertials(robot, pi, tmp_path / "model.urdf")
    src_tags, src_root = _tags(robot.urdf_path)
    new_tags, new_root = _tags(out)
    assert new_tags == src_tags and len(new_tags["visual"]) > 0  # every visual/collision element, byte-equal
    assert [ln.get("name") for ln in new_root.iter("link")] == [ln.get("name") for ln in src_root.iter("link")]
    assert [j.get("name") for j in new_root.iter("joint")] == [j.get("name") for j in src_root.iter("joint")]
    model = pin.buildModelFromUrdf(str(out))
    for j in range(1, robot.model.njoints):
        jj = model.getJointId(robot.model.names[j])
        np.testing.assert_allclose(model.inertias[jj].toDynamicParameters(), pi[10 * (j - 1): 10 * j], atol=1e-9)
    # the meshes resolve: Pinocchio builds the visual geometry of the patched file
    from pathlib import Path

    pkg = Path(robot.urdf_path).resolve().parents[4]  # share/, holding example-robot-data/ (package://)
    geom = pin.buildGeomFromUrdf(model, str(out), pin.GeometryType.VISUAL, package_dirs=[str(pkg)])
    assert geom.ngeoms == len(src_tags["visual"])


def test_panda_hand_is_lumped_into_link7(tmp_path):
    """Fixed links (link8, hand) lose their inertial: link7's body is exactly the identified one."""
    robot = load_robot("panda")
    pi = _truth_pi(robot, 1)
    _, root = _tags(patch_urdf_inertials(robot, pi, tmp_path / "p.urdf"))
    links = {ln.get("name"): ln for ln in root.iter("link")}
    assert links["panda_hand"].find("inertial") is None and links["panda_link7"].find("inertial") is not None


def test_joint_terms_and_fallback(tmp_path):
    robot = load_robot("ur5")
    pi = _truth_pi(robot, 0)
    terms = JointTerms(("elbow_joint",), fv=np.array([0.5]), fc=np.array([1.25]))
    path, how = export_urdf(robot, pi, tmp_path / "a.urdf", joint_terms=terms)
    assert how.startswith("patched")
    dyn = [j for j in ET.parse(path).getroot().iter("joint") if j.get("name") == "elbow_joint"][0].find("dynamics")
    assert float(dyn.get("damping")) == 0.5 and float(dyn.get("friction")) == 1.25
    locked = load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"])
    pl = _truth_pi(locked, 0)
    path, how = export_urdf(locked, pl, tmp_path / "b.urdf")
    assert how.startswith("generated (") and "locked" in how
    assert pin.buildModelFromUrdf(str(path)).nv == locked.nv
    bad = pi.copy()
    bad[0] = -1.0
    with pytest.raises(PhysicalConsistencyError, match="shoulder_pan_joint"):
        export_urdf(robot, bad, tmp_path / "c.urdf")
    assert not (tmp_path / "c.urdf").exists()

"""Issue 24 item 7: a URDF whose collision meshes are missing (or outside the allowed folders) is
one warning per load naming each file and the bounding ellipsoid each body gets instead, and
result.json records every body's ellipsoid source."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless import load_robot
from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import RobotModelWarning
from sensorless.excitation import random_fourier
from sensorless.identification import auto_ellipsoids
from sensorless.identification.ellipsoids import KINEMATIC_MARGIN, load_geometry, missing_meshes
from sensorless.testing import perturbed_truth, synthetic_trajectory

# a closed tetrahedron, 10 cm
STL = "solid s\n" + "".join(
    f"facet normal 0 0 0\nouter loop\n{''.join(f'vertex {x} {y} {z}' + chr(10) for x, y, z in tri)}endloop\nendfacet\n"
    for tri in [((0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)), ((0, 0, 0), (0, 0, 0.1), (0.1, 0, 0)),
                ((0, 0, 0), (0, 0.1, 0), (0, 0, 0.1)), ((0.1, 0, 0), (0, 0, 0.1), (0, 0.1, 0))]) + "endsolid s\n"


def _link(name: str, mass: float, z: float, mesh: str) -> str:
    return (f'<link name="{name}"><inertial><origin xyz="0 0 {z}"/><mass value="{mass}"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.005"/></inertial>'
            f'<collision><geometry><mesh filename="{mesh}"/></geometry></collision></link>')


def _arm(folder: Path, with_l2_mesh: bool) -> Path:
    """base → j1 (z) → l1 (meshes/l1.stl) → j2 (y, 0.3 m up) → l2 (meshes/l2.stl, written only if asked)."""
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    (folder / "meshes/l1.stl").write_text(STL)
    if with_l2_mesh:
        (folder / "meshes/l2.stl").write_text(STL)
    lim = '<limit lower="-3" upper="3" effort="50" velocity="3"/>'
    path = folder / "arm.urdf"
    path.write_text('<robot name="arm"><link name="base"/>' + _link("l1", 2.0, 0.15, "meshes/l1.stl")
                    + _link("l2", 1.0, 0.1, "meshes/l2.stl")
                    + f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>{lim}</joint>'
                    + '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/>'
                    + f'<axis xyz="0 1 0"/>{lim}</joint></robot>')
    return path


def _load(path: Path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        robot = load_robot(path)
        ell = auto_ellipsoids(robot)
        auto_ellipsoids(robot)  # a second use of the same robot: no second warning
    return robot, ell, [str(w.message) for w in caught if issubclass(w.category, RobotModelWarning)]


def test_missing_mesh_is_one_warning_naming_the_file_and_the_ellipsoid_used_instead(tmp_path):
    robot, ell, msgs = _load(_arm(tmp_path / "a", with_l2_mesh=False))
    assert len(msgs) == 1, msgs
    assert "'meshes/l2.stl' (link l2): not found" in msgs[0] and "l1.stl" not in msgs[0]
    assert f"from the kinematics (joint positions and frames, {100 * KINEMATIC_MARGIN:g} cm margin) for j2" in msgs[0]
    assert [m["body"] for m in missing_meshes(robot)] == ["j2"]
    assert ell["j1"].source == "collision geometry" and ell["j2"].source == "kinematics (collision mesh missing)"
    # the ellipsoid j2 gets is exactly the kinematic one (joint positions, frames and prior CoM, 6 cm margin)
    kin = auto_ellipsoids(robot, geometry=None)["j2"]
    np.testing.assert_allclose(ell["j2"].shape_matrix, kin.shape_matrix, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ell["j2"].center, kin.center, atol=1e-12)
    # with the mesh present: no warning, and j2's ellipsoid is built from it (a different one)
    robot2, ell2, msgs2 = _load(_arm(tmp_path / "b", with_l2_mesh=True))
    assert msgs2 == [] and ell2["j2"].source == "collision geometry" and not missing_meshes(robot2)
    assert not np.allclose(ell2["j2"].shape_matrix, kin.shape_matrix, rtol=1e-3)
    assert load_geometry(robot2).ngeoms == 2


def test_identify_records_the_ellipsoid_source_per_body(tmp_path):
    path = _arm(tmp_path / "a", with_l2_mesh=False)
    robot = load_robot(path)
    truth = perturbed_truth(robot, rng=0)
    log = write_npz(synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(50, 8.0), noise_std=0.02, rng=2),
                    tmp_path / "log.npz")
    res = CliRunner().invoke(app, ["identify", "--robot", str(path), "--data", str(log), "--method", "lmi",
                                   "--gamma", "1e-3", "--joint-terms", "fv,fc,offset", "--coulomb-smoothing", "0.02",
                                   "--no-plot", "--out", str(tmp_path / "id")])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.splitlines() if "left out of the bounding ellipsoids" in ln]
    assert len(lines) == 1 and "meshes/l2.stl" in lines[0] and "for j2" in lines[0]
    doc = json.loads((tmp_path / "id/result.json").read_text())
    assert doc["diagnostics"]["ellipsoid_sources"] == {"j1": "collision geometry",
                                                       "j2": "kinematics (collision mesh missing)"}
    assert doc["diagnostics"]["lmi"]["settings"]["ellipsoids"]["j2"]["source"] == "kinematics (collision mesh missing)"


@pytest.mark.parametrize("ref", ["../outside/l2.stl", "package://nowhere/l2.stl"])
def test_a_mesh_outside_the_allowed_folders_is_reported_the_same_way(tmp_path, ref, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    path = _arm(tmp_path / "a", with_l2_mesh=False)
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside/l2.stl").write_text(STL)
    path.write_text(path.read_text().replace("meshes/l2.stl", ref))
    _, ell, msgs = _load(path)
    assert len(msgs) == 1 and repr(ref) in msgs[0] and "for j2" in msgs[0] and "`package_paths=DIR`" in msgs[0]
    assert ell["j2"].source == "kinematics (collision mesh missing)"

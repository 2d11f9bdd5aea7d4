"""Untrusted robot descriptions (issue 26 item 2), file references (sensorless.robot_paths): every mesh,
package:// URI and MJCF include stays in the description's folder and the package paths the user names.
The xacro half is tests/test_xacro_expand.py."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.errors import RobotModelError, RobotModelWarning
from sensorless.identification.ellipsoids import load_geometry
from sensorless.robot import load_robot

runner = CliRunner()


STL = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.1 0 0\nvertex 0 0.1 0.1\nendloop\nendfacet\nendsolid s\n"


def _urdf(folder: Path, meshes: list[str]) -> Path:
    cols = "".join(f'<collision><geometry><mesh filename="{m}"/></geometry></collision>' for m in meshes)
    path = folder / "r.urdf"
    path.write_text('<robot name="r"><link name="base"/><link name="l1"><inertial><mass value="1"/>'
                    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
                    f'{cols}</link><joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
                    '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    return path


@pytest.fixture
def tree(tmp_path, monkeypatch):
    """desc/ (the URDF and meshes/in.stl), outside/secret.stl and pkgs/secret_pkg/m.stl."""
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    for sub in ("desc/meshes", "outside", "pkgs/secret_pkg"):
        (tmp_path / sub).mkdir(parents=True)
    (tmp_path / "desc/meshes/in.stl").write_text(STL)
    (tmp_path / "outside/secret.stl").write_text(STL)
    (tmp_path / "pkgs/secret_pkg/m.stl").write_text(STL)
    return tmp_path


def _geometry(urdf: Path, monkeypatch, **kw):
    import pinocchio as pin

    seen = []
    real = pin.buildGeomFromUrdfString
    monkeypatch.setattr(pin, "buildGeomFromUrdfString", lambda m, text, *a, **k: seen.append(text) or real(m, text, *a, **k))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        geom = load_geometry(load_robot(urdf, **kw))
    return geom, [str(w.message) for w in caught if issubclass(w.category, RobotModelWarning)], seen[0]


def test_mesh_escapes_are_dropped_with_a_warning_and_never_read(tree, monkeypatch):
    escapes = ["../outside/secret.stl", "../../../../../../etc/passwd", str(tree / "outside/secret.stl"),
               "/etc/passwd", "package://secret_pkg/m.stl", "file:///etc/passwd"]
    geom, msgs, text = _geometry(_urdf(tree / "desc", ["meshes/in.stl", *escapes]), monkeypatch)
    assert [Path(o.meshPath) for o in geom.geometryObjects] == [tree / "desc/meshes/in.stl"]
    assert len(msgs) == 1 and all(repr(e) in msgs[0] for e in escapes)  # one warning naming every file
    assert "no package folder is given" in msgs[0] and "`package_paths=DIR`" in msgs[0]
    assert "from their other collision shapes and joint positions for j1" in msgs[0]  # l1 keeps meshes/in.stl
    assert "passwd" not in text and "outside" not in text and "secret_pkg" not in text  # never handed to the mesh loader


def test_package_path_allows_its_meshes(tree, monkeypatch):
    geom, msgs, _ = _geometry(_urdf(tree / "desc", ["meshes/in.stl", "package://secret_pkg/m.stl",
                                                    "../outside/secret.stl"]),
                              monkeypatch, package_paths=[tree / "pkgs", tree / "outside"])
    assert sorted(Path(o.meshPath).name for o in geom.geometryObjects) == ["in.stl", "m.stl", "secret.stl"] and not msgs
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tree / "pkgs"))
    geom, msgs, _ = _geometry(_urdf(tree / "desc", ["package://secret_pkg/m.stl"]), monkeypatch)
    assert geom.ngeoms == 1 and not msgs


def test_symlink_out_of_the_folder_is_an_escape(tree, monkeypatch):
    (tree / "desc/meshes/link.stl").symlink_to(tree / "outside/secret.stl")
    geom, msgs, _ = _geometry(_urdf(tree / "desc", ["meshes/link.stl"]), monkeypatch)
    assert geom.ngeoms == 0 and "meshes/link.stl" in msgs[0]


MJCF = """<mujoco model="m">{extra}<worldbody><body name="b"><joint name="j" type="hinge"/>
<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody></mujoco>"""


@pytest.mark.parametrize("extra, what", [
    ('<include file="/etc/passwd"/>', "'/etc/passwd' is an absolute path outside"),
    ('<include file="../outside/secret.xml"/>', "'../outside/secret.xml' is a path outside"),
    ('<compiler meshdir="/etc"/>', "<compiler meshdir>: '/etc' is an absolute path"),
    ('<compiler assetdir="../outside"/>', "<compiler assetdir>: '../outside'"),
    ('<asset><mesh name="s" file="/etc/passwd"/></asset>', "<mesh file>: '/etc/passwd'"),
    ('<include file="sub.xml"/>', "sub.xml: <include>: '/etc/shadow' is an absolute path"),  # nested
])
def test_mjcf_escapes_are_refused(tree, extra, what):
    (tree / "outside/secret.xml").write_text("<mujoco/>")
    (tree / "desc/sub.xml").write_text('<mujoco><include file="/etc/shadow"/></mujoco>')
    path = tree / "desc/m.xml"
    path.write_text(MJCF.format(extra=extra))
    with pytest.raises(RobotModelError, match="`package_paths=DIR`") as err:
        load_robot(path)
    assert what in str(err.value) and "\n" not in str(err.value)


def test_mjcf_inside_its_folder_loads(tree):
    (tree / "desc/sub.xml").write_text('<mujoco><compiler angle="radian"/></mujoco>')
    path = tree / "desc/m.xml"
    path.write_text(MJCF.format(extra='<compiler meshdir="meshes"/><include file="sub.xml"/>'
                                      '<asset><mesh name="s" file="in.stl"/></asset>'))
    r = load_robot(path)
    assert r.joint_names == ("j",) and np.isclose(r.model.inertias[1].mass, 1.0)
    assert load_robot(path, package_paths=[tree / "outside"]).joint_names == ("j",)


@pytest.mark.parametrize("command", ["identify", "excite", "predict", "estimate-force", "monitor", "payload",
                                     "drive-gains"])
def test_every_robot_command_has_the_consent_and_package_options(command):
    res = runner.invoke(app, [command, "--help"], terminal_width=200)
    assert res.exit_code == 0 and "--trust-xacro" in res.output and "--package-path" in res.output

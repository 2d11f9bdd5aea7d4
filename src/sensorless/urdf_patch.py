"""Export identified inertias by patching the source URDF's ``<inertial>`` tags.

Everything else of the source file survives (meshes, visuals, collisions, materials, fixed
links, sensors, ``<gazebo>``/``<transmission>`` blocks, comments), so the model opens in
RViz as before. Pinocchio body j (joint ``model.names[j]``) is the joint's child link
merged with every link hanging below it by fixed joints (Pinocchio's parser lumps them);
its identified inertia, expressed in the joint frame = the child link's frame, is written
into the child link (CoM as ``<origin xyz>``, ``rpy = 0``, inertia about the CoM via
:func:`sensorless.parameters.urdf_inertial`) and the merged fixed links lose their
``<inertial>``: the lumped body is then exactly the identified one. On a floating-base
robot body 1 is the URDF root link. Relative mesh paths are made absolute (the patched
file is written elsewhere); ``package://`` URIs are kept.

The patched file is parsed back with Pinocchio and each body's inertia compared with the
identified one; any mismatch, a reduced model (locked joints), or joints the URDF and the
model do not share raise :class:`~sensorless.errors.RobotModelError`.
:func:`export_urdf` then falls back to :func:`sensorless.export.write_urdf`.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from .errors import PhysicalConsistencyError, RobotModelError, SensorlessError
from .io import atomic_write_text
from .parameters import JointTerms, as_bodies, urdf_inertial
from .robot import Robot

__all__ = ["patch_urdf_inertials", "export_urdf"]


def _f(x: float) -> str:
    return repr(float(x))


def _parse(path: Path) -> ET.ElementTree:
    try:
        return ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except (ET.ParseError, OSError) as exc:
        raise RobotModelError(f"{path}: cannot parse the source URDF ({exc})") from None


def _body_links(root: ET.Element, robot: Robot, src: str) -> dict[int, tuple[str, list[str]]]:
    """Pinocchio joint index → (link carrying the body, fixed links merged into it)."""
    joints = root.findall("joint")
    links = [ln.get("name") for ln in root.findall("link")]
    kids: dict[str, list[tuple[str, str]]] = {}
    for j in joints:
        kids.setdefault(j.find("parent").get("link"), []).append((j.get("type"), j.find("child").get("link")))
    child_of = {j.get("name"): j.find("child").get("link") for j in joints}
    moving = {j.get("name") for j in joints if j.get("type") != "fixed"}
    names = list(robot.model.names)
    first = 2 if robot.floating_base else 1
    model_joints = set(names[first:])
    if moving != model_joints:
        raise RobotModelError(
            f"{src}: the URDF's moving joints {sorted(moving - model_joints)} / the model's {sorted(model_joints - moving)} "
            "differ (locked or renamed joints); the URDF cannot be patched")
    out = {}
    for j in range(1, robot.model.njoints):
        if j == 1 and robot.floating_base:
            roots = [ln for ln in links if ln not in set(child_of.values())]
            if len(roots) != 1:
                raise RobotModelError(f"{src}: expected one root link, found {roots}")
            link = roots[0]
        else:
            link = child_of[names[j]]
        merged, stack = [], [link]
        while stack:
            for jtype, child in kids.get(stack.pop(), []):
                if jtype == "fixed":
                    merged.append(child)
                    stack.append(child)
        out[j] = (link, merged)
    return out


def _set_inertial(link: ET.Element, p: np.ndarray) -> None:
    d = urdf_inertial(p)
    old = link.find("inertial")
    pos = list(link).index(old) if old is not None else 0
    if old is not None:
        link.remove(old)
    new = ET.Element("inertial")
    new.text, new.tail = "\n      ", "\n    "
    ET.SubElement(new, "origin", xyz=" ".join(_f(x) for x in d["xyz"]), rpy="0 0 0").tail = "\n      "
    ET.SubElement(new, "mass", value=_f(d["mass"])).tail = "\n      "
    ET.SubElement(new, "inertia", **{k: _f(d[k]) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}).tail = "\n    "
    link.insert(pos, new)


def patch_urdf_inertials(robot: Robot, pi: np.ndarray, path: str | os.PathLike, *, source: str | os.PathLike | None = None,
                         joint_terms: JointTerms | None = None) -> Path:
    """Write ``source`` (default ``robot.urdf_path``) to ``path`` with the identified inertial
    parameters ``pi`` ((10 n_bodies,) Pinocchio order) in its ``<inertial>`` tags (module docstring).
    ``joint_terms`` set ``<dynamics damping=fv friction=fc>``. Atomic write; returns the path."""
    src = source or getattr(robot, "urdf_path", None)
    if not src:
        raise RobotModelError(f"robot '{robot.name}' has no source URDF to patch")
    src = Path(src)
    if np.size(pi) != 10 * robot.n_bodies:
        raise RobotModelError(f"expected {10 * robot.n_bodies} inertial parameters, got {np.shape(pi)}")
    P = as_bodies(np.ravel(pi))
    names = list(robot.model.names)
    for k in range(robot.n_bodies):
        if not P[k, 0] > 0.0:
            raise PhysicalConsistencyError(
                f"body '{names[k + 1]}' has mass {P[k, 0]:g} <= 0 and cannot be written as a URDF inertial; "
                "export physically consistent parameters (LMI identification)")
    tree = _parse(src)
    root = tree.getroot()
    if root.tag != "robot":
        raise RobotModelError(f"{src}: root element is <{root.tag}>, not <robot>")
    by_name = {ln.get("name"): ln for ln in root.findall("link")}
    for j, (link, merged) in _body_links(root, robot, str(src)).items():
        _set_inertial(by_name[link], P[j - 1])
        for m in merged:
            old = by_name[m].find("inertial")
            if old is not None:
                by_name[m].remove(old)
    if joint_terms is not None:
        jel = {j.get("name"): j for j in root.findall("joint")}
        for k, name in enumerate(joint_terms.joint_names):
            if name not in jel:
                raise RobotModelError(f"{src}: joint_terms name joint '{name}' the URDF does not have")
            dyn = jel[name].find("dynamics")
            if dyn is None:
                dyn = ET.SubElement(jel[name], "dynamics")
            dyn.set("damping", _f(joint_terms.fv[k]))
            dyn.set("friction", _f(joint_terms.fc[k]))
    for mesh in root.iter("mesh"):
        fn = mesh.get("filename", "")
        if fn and "://" not in fn and not os.path.isabs(fn):
            mesh.set("filename", str((src.parent / fn).resolve()))
    text = ('<?xml version="1.0"?>\n<!-- sensorless: identified inertials patched into '
            f"{src.name}; fixed links merged into a moving body carry no inertial -->\n"
            + ET.tostring(root, encoding="unicode") + "\n")
    _check(text, robot, P, str(src))
    return atomic_write_text(path, text)


def _check(text: str, robot: Robot, P: np.ndarray, src: str) -> None:
    """Parse the patched file with Pinocchio: every body's inertia must equal the identified one."""
    try:
        model = (pin.buildModelFromXML(text, pin.JointModelFreeFlyer()) if robot.floating_base
                 else pin.buildModelFromXML(text))
    except Exception as exc:  # Pinocchio raises bare RuntimeError/ValueError
        raise RobotModelError(f"{src}: Pinocchio cannot parse the patched URDF ({exc})") from None
    for j in range(1, robot.model.njoints):
        name = robot.model.names[j]
        if j == 1 and robot.floating_base:
            jj = 1
        elif model.existJointName(name):
            jj = model.getJointId(name)
        else:
            raise RobotModelError(f"{src}: joint '{name}' is missing from the patched URDF")
        got = model.inertias[jj].toDynamicParameters()
        if not np.allclose(got, P[j - 1], rtol=1e-9, atol=1e-9 * max(1.0, float(np.abs(P[j - 1]).max()))):
            raise RobotModelError(f"{src}: body '{name}' of the patched URDF does not reload as identified "
                                  f"({np.round(got, 6)} vs {np.round(P[j - 1], 6)})")


def export_urdf(robot: Robot, pi: np.ndarray, path: str | os.PathLike,
                joint_terms: JointTerms | None = None) -> tuple[Path, str]:
    """The patched source URDF when possible, else :func:`~sensorless.export.write_urdf`'s
    generated one. Returns (path, how): how = "patched <source>" or "generated (<reason>)"."""
    from .export import write_urdf

    try:
        out = patch_urdf_inertials(robot, pi, path, joint_terms=joint_terms)
        return out, f"patched {robot.urdf_path}"
    except PhysicalConsistencyError:
        raise
    except SensorlessError as exc:
        return write_urdf(robot, pi, path, joint_terms=joint_terms), f"generated ({exc})"

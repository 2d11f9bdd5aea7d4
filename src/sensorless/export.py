"""Export identified parameters: a URDF generated from the Pinocchio model, joint terms as JSON.

The URDF is written from the Pinocchio model, not by editing the source URDF: the
parser merges fixed links into their parent body, so identified per-body parameters
do not map to the source's links. One link is written per Pinocchio joint ``j >= 1``,
named after the first BODY frame attached to ``j`` (else ``"<joint>_link"``), whose link
frame is the joint frame; its ``<inertial>`` holds the mass, the CoM as origin
(``rpy = 0``) and the inertia about the CoM (:func:`sensorless.parameters.urdf_inertial`).
Each joint's origin is ``model.jointPlacements[j]``. Fixed links, visuals and collisions
are not written; operational frames (``OP_FRAME``, e.g. a tool tip added in code) are written
as massless links on fixed joints with ``frames=True``, so the file keeps them.

* Fixed base: the root link is the model's root BODY frame name (else ``"base_link"``)
  and carries no inertial (it does not move).
* Floating base (free-flyer joint 1): the joint is not written and its body becomes the
  URDF root link; load the file with ``load_robot(path, floating_base=True)`` /
  ``pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())``. (A non-identity
  free-flyer placement is dropped: it only re-parameterises the base pose.)
* URDF needs ``mass > 0``: a body with ``mass <= 0`` raises
  :class:`~sensorless.errors.PhysicalConsistencyError`. Export physically consistent
  parameters (LMI identification, or the consistent projection closest to a prior)
  rather than raw least-squares estimates.
* ``joint_terms`` adds ``<dynamics damping=fv friction=fc>``; offsets and armature have
  no URDF field, keep them with :func:`write_joint_terms`.
"""

from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from .errors import PhysicalConsistencyError, RobotModelError
from .io import atomic_write_text
from .parameters import JointTerms, as_bodies, is_physically_consistent, urdf_inertial
from .robot import Robot

__all__ = ["write_urdf", "write_joint_terms", "read_joint_terms", "link_names", "joint_axis"]

_REVOLUTE = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"}
_CONTINUOUS = {"JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned"}
_PRISMATIC = {"JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"}
_FMAX = np.finfo(float).max


def _f(x: float) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _atomic_write(path: str | os.PathLike, text: str) -> Path:
    return atomic_write_text(path, text)


def link_names(model: pin.Model, floating: bool) -> list[str]:
    """The link (body) name per joint index, as the exported files name them: the first BODY frame on the
    joint, else ``<joint>_link`` (0 = the fixed root, "base_link" without a frame; "" when floating), unique."""
    names: list[str] = [""] if floating else []
    joints = set(model.names)
    for j in range(len(names), model.njoints):
        body = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == j]
        body = [b for b in body if b != "universe"]
        name = body[0] if body else ("base_link" if j == 0 else f"{model.names[j]}_link")
        while name in names or name in joints:
            name += "_"
        names.append(name)
    return names


def joint_axis(model: pin.Model, j: int) -> np.ndarray:
    """Axis of a 1-DoF joint from its motion subspace (angular part if revolute, else linear)."""
    jm = model.joints[j]
    jd = jm.createData()
    jm.calc(jd, pin.neutral(model))
    S = np.asarray(jd.S).reshape(6)
    return S[:3] if jm.shortname() in _PRISMATIC else S[3:]


def write_urdf(robot: Robot, pi: np.ndarray, path: str | os.PathLike, joint_terms: JointTerms | None = None,
               *, frames: bool = False) -> Path:
    """Write ``robot``'s kinematics with the inertial parameters ``pi`` as a URDF at ``path``.

    ``pi`` is the stacked ``(10 n_bodies,)`` vector (or ``(n_bodies, 10)``). Returns the path.
    ``frames``: also write the operational frames (massless links on fixed joints).
    The file is written atomically (temporary file + ``os.replace``).
    """
    model = robot.model
    if np.size(pi) != 10 * robot.n_bodies:
        raise RobotModelError(f"expected {10 * robot.n_bodies} inertial parameters, got {np.shape(pi)}")
    P = as_bodies(np.ravel(pi))
    names = link_names(model, robot.floating_base)
    for k in range(robot.n_bodies):
        if not P[k, 0] > 0.0:
            raise PhysicalConsistencyError(
                f"body '{model.names[k + 1]}' (link '{names[k + 1]}') has mass {P[k, 0]:g} <= 0 and "
                "cannot be written as a URDF inertial; export physically consistent parameters "
                "(LMI identification or the consistent projection closest to a prior)"
            )
    terms = {}
    if joint_terms is not None:
        terms = {j: k for k, j in enumerate(joint_terms.joint_names)}
        unknown = [j for j in terms if j not in model.names]
        if unknown:
            raise RobotModelError(f"joint_terms name joint(s) {unknown} the robot does not have")

    root = ET.Element("robot", name=robot.name)
    floating = robot.floating_base
    if not floating:
        ET.SubElement(root, "link", name=names[0])
    for j in range(1, model.njoints):
        link = ET.SubElement(root, "link", name=names[j])
        d = urdf_inertial(P[j - 1])
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz=_vec(d["xyz"]), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_f(d["mass"]))
        ET.SubElement(inertial, "inertia", **{k: _f(d[k]) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")})
        if floating and j == 1:
            continue
        jm = model.joints[j]
        short = jm.shortname()
        if short in _REVOLUTE:
            jtype = "revolute"
        elif short in _CONTINUOUS:
            jtype = "continuous"
        elif short in _PRISMATIC:
            jtype = "prismatic"
        else:
            raise RobotModelError(f"joint '{model.names[j]}' of type {short} cannot be written to URDF")
        parent = model.parents[j]
        if floating and parent == 0:
            raise RobotModelError(f"joint '{model.names[j]}' is attached to the world of a floating-base robot")
        joint = ET.SubElement(root, "joint", name=model.names[j], type=jtype)
        M = model.jointPlacements[j]
        ET.SubElement(joint, "origin", xyz=_vec(M.translation), rpy=_vec(pin.rpy.matrixToRpy(M.rotation)))
        ET.SubElement(joint, "parent", link=names[parent])
        ET.SubElement(joint, "child", link=names[j])
        ET.SubElement(joint, "axis", xyz=_vec(joint_axis(model, j)))
        iq, iv = jm.idx_q, jm.idx_v
        lim = {
            "effort": _f(np.clip(model.effortLimit[iv], 0.0, _FMAX)),
            "velocity": _f(np.clip(model.velocityLimit[iv], 0.0, _FMAX)),
        }
        if jtype != "continuous":
            lim = {
                "lower": _f(np.clip(model.lowerPositionLimit[iq], -_FMAX, _FMAX)),
                "upper": _f(np.clip(model.upperPositionLimit[iq], -_FMAX, _FMAX)),
                **lim,
            }
        ET.SubElement(joint, "limit", **lim)
        if model.names[j] in terms:
            k = terms[model.names[j]]
            ET.SubElement(joint, "dynamics", damping=_f(joint_terms.fv[k]), friction=_f(joint_terms.fc[k]))
    if frames:
        _write_frames(root, model, names)
    ET.indent(root)
    note = "" if is_physically_consistent(P) else "<!-- WARNING: some bodies are not physically consistent -->\n"
    text = '<?xml version="1.0"?>\n<!-- generated by sensorless.export.write_urdf -->\n' + note
    return _atomic_write(path, text + ET.tostring(root, encoding="unicode") + "\n")


def _write_frames(root: ET.Element, model: pin.Model, names: list[str]) -> None:
    """Each OP_FRAME as a link without inertial on a fixed joint to its parent joint's link."""
    taken = set(names) | set(model.names)
    for f in model.frames:
        if f.type != pin.FrameType.OP_FRAME or f.name in taken or f"{f.name}_joint" in taken:
            continue
        taken |= {f.name, f"{f.name}_joint"}
        ET.SubElement(root, "link", name=f.name)
        joint = ET.SubElement(root, "joint", name=f"{f.name}_joint", type="fixed")
        M = f.placement  # in the parent joint's frame = the link frame of that joint
        ET.SubElement(joint, "origin", xyz=_vec(M.translation), rpy=_vec(pin.rpy.matrixToRpy(M.rotation)))
        ET.SubElement(joint, "parent", link=names[f.parentJoint])
        ET.SubElement(joint, "child", link=f.name)


def write_joint_terms(joint_terms: JointTerms, path: str | os.PathLike) -> Path:
    """Write ``joint_terms.to_dict()`` as JSON (atomically)."""
    return _atomic_write(path, json.dumps(joint_terms.to_dict(), indent=2) + "\n")


def read_joint_terms(path: str | os.PathLike) -> JointTerms:
    """Read a file written by :func:`write_joint_terms`."""
    from .errors import ParameterError
    from .io import read_json

    doc = read_json(path, "joint terms file", error=ParameterError)
    if not isinstance(doc, dict):
        raise ParameterError(f"{path}: expected a JSON object of joints, got {type(doc).__name__}")
    return JointTerms.from_dict(doc)

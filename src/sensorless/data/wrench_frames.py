"""Contact wrenches logged in a model frame, expressed where the contact rows expect them.

The contact maps (:mod:`sensorless.regressor.contact`) take each measured wrench
w = [f; τ], the wrench the environment exerts on the robot, in world axes about the origin
of its contact frame C (Pinocchio LOCAL_WORLD_ALIGNED), in the order of the contact frames.
A sole or an F/T sensor logs it in the axes of its own frame S, about S's origin. With
Pinocchio's forward kinematics at each sample (the base pose included for a floating base),
R_S the world rotation of S and p_S, p_C the world origins,

    f = R_S f_S,        τ_C = R_S τ_S + (p_S − p_C) × f.

Point contacts (3 columns per contact) rotate the force only. :func:`wrench_frame_map` turns
the command-line spec (one frame per contact frame, ``contact`` = each contact's own frame,
``world`` = already world-aligned at the contact) into ``{contact frame: wrench frame}``;
:func:`express_wrenches` applies it to ``extras["contact_forces"]`` (or, when absent, the
``extras["wrench"]`` of a ROS bag's WrenchStamped topics).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import DataError, OptionError, RobotModelError, did_you_mean, python_only, setting
from .trajectory import Trajectory

__all__ = ["WORLD", "CONTACT", "check_frame", "wrench_frame_map", "express_wrenches"]

#: the wrench is already in world axes at its contact frame (nothing to do)
WORLD = "world"
#: the wrench is in its contact frame's own axes (a sole frame)
CONTACT = "contact"
_KEYS = ("contact_forces", "wrench")


def _items(spec: "str | Sequence[str] | None") -> list[str]:
    if spec is None:
        return []
    parts = [spec] if isinstance(spec, str) else list(spec)
    return [p.strip() for s in parts for p in str(s).split(",") if p.strip()]


def check_frame(robot, name: str, what: str = "`wrench_frames`") -> int:
    """Frame id of ``name`` in ``robot``; a RobotModelError with the closest frame names otherwise."""
    model = robot.model
    if model.existFrame(name):
        return model.getFrameId(name)
    names = [f.name for f in model.frames]
    hint = did_you_mean(name, names, cutoff=0.5)
    hint = f"; {hint}" if hint else ""
    raise RobotModelError(f"{what}: the model {robot.name} has no frame '{name}'{hint} "
                          f"(`sensorless frames --robot ...` lists its {len(names)} frames"
                          f"{python_only('sensorless.robot.frame_table(robot) lists them')})")


def wrench_frame_map(spec: "str | Sequence[str] | Mapping[str, str] | None", contact_frames: Sequence[str],
                     robot=None) -> dict[str, str] | None:
    """``{contact frame: frame its wrench is logged in}`` from ``spec`` (module docstring), or None
    when no frame is given (the wrenches are world-aligned). ``spec``: one frame per contact frame, in their
    order (comma-separated or a list), or one of ``contact`` / ``world`` for all; a mapping is
    checked and returned. With ``robot``, every frame name is checked against the model."""
    contact_frames = list(contact_frames)
    if isinstance(spec, Mapping):
        if list(spec) != contact_frames:
            raise OptionError(f"wrench frames are given for {list(spec)} but the contact frames are {contact_frames}")
        items = [str(v) for v in spec.values()]
    else:
        items = _items(spec)
    if not items:
        return None
    if not contact_frames:
        raise OptionError(f"{setting('wrench_frames')} needs {setting('contact_frames')} (one wrench frame per contact "
                          "frame, in that order)")
    if len(items) == 1 and items[0] in (WORLD, CONTACT):
        items = items * len(contact_frames)
    if len(items) != len(contact_frames):
        raise OptionError(f"{setting('wrench_frames')} gives {len(items)} frame(s) {items} for {len(contact_frames)} contact "
                          f"frame(s) {contact_frames}: give one per contact frame, in the same order (or 'contact' "
                          "for each contact's own frame, 'world' for world-aligned wrenches)")
    out = {c: (c if s == CONTACT else s) for c, s in zip(contact_frames, items)}
    if robot is not None:
        for c, s in out.items():
            check_frame(robot, c, setting("contact_frames"))
            if s != WORLD:
                check_frame(robot, s)
    return out


def _wrench_array(traj: Trajectory, n_c: int) -> tuple[str, np.ndarray]:
    key = next((k for k in _KEYS if traj.extras.get(k) is not None), None)
    if key is None:
        raise DataError(f"{setting('wrench_frames')} was given but the log has no measured wrenches ('contact_forces', or a ROS "
                        "bag's 'wrench' topics)", traj.source)
    f = np.asarray(traj.extras[key], dtype=float)
    n = len(traj)
    if f.ndim == 2 and f.shape[0] == n and f.shape[1] in (3 * n_c, 6 * n_c):
        f = f.reshape(n, n_c, f.shape[1] // n_c)
    if not (f.ndim == 3 and f.shape[:2] == (n, n_c) and f.shape[2] in (3, 6)):
        raise DataError(f"'{key}' has shape {np.shape(traj.extras[key])}; with {setting('wrench_frames')} for {n_c} contact "
                        f"frame(s) expected ({n}, {n_c}, 3 or 6) or ({n}, {n_c}·3 or {n_c}·6)", traj.source)
    return key, f


def express_wrenches(traj: Trajectory, robot, frames: Mapping[str, str]) -> Trajectory:
    """``traj`` with its wrenches, logged in the model frames ``frames`` (``{contact frame: wrench
    frame}``, in the contact frames' order), in world axes about the contact frames (module
    docstring), as ``extras["contact_forces"]`` (N, n_contacts, 3|6); a bag's ``extras["wrench"]``
    is moved there (all ``world``: unchanged otherwise)."""
    import pinocchio as pin  # imported on use (start-up time of the data layer)

    frames = dict(frames)
    contacts = list(frames)
    cids = [check_frame(robot, c, setting("contact_frames")) for c in contacts]
    sids = [None if s == WORLD else check_frame(robot, s) for s in frames.values()]
    key, f = _wrench_array(traj, len(contacts))
    moving = any(sid is not None for sid in sids)
    if moving and getattr(robot, "floating_base", False) and traj.base_q is None:
        raise DataError(f"{setting('wrench_frames')}: the sensor frames move with the floating base, but the log has no base pose "
                        "('base_q'); log the base pose (position + quaternion) or give world-aligned wrenches",
                        traj.source)
    perm = robot.joint_order(traj.joint_names, traj.source)
    Q = robot.full_configuration(traj.q[:, perm], traj.base_q)
    model, data = robot.model, robot.data
    out = f.copy()
    six = f.shape[2] == 6
    for i in range(len(traj) if moving else 0):
        pin.framesForwardKinematics(model, data, Q[i])
        for k, (cid, sid) in enumerate(zip(cids, sids)):
            if sid is None:
                continue
            S = data.oMf[sid]
            force = S.rotation @ f[i, k, :3]
            out[i, k, :3] = force
            if six:
                out[i, k, 3:] = S.rotation @ f[i, k, 3:] + np.cross(S.translation - data.oMf[cid].translation, force)
    extras = {k: v for k, v in traj.extras.items() if k != key}
    extras["contact_forces"] = out
    moved = {c: s for c, s in frames.items() if s != WORLD}
    prov = {**traj.provenance, "contact_forces": f"logged as '{key}' in the frames {moved}; expressed in world axes "
            "at the contact frames with the logged kinematics (--wrench-frame)", "wrench_frames": frames}
    return traj.with_(extras=extras, provenance=prov)

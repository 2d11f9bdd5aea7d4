"""What a row of a figure is: its unit and the limb it belongs to.

A row is a joint of the robot (revolute: N·m, rad; prismatic: N, m), a floating base's
generalized-force row (``base_vx``..``base_vz``: N, ``base_wx``..``base_wz``: N·m) or a
coordinate of a coupled robot (a transmission; the unit of the tree joints it drives).

**Limbs.** A robot with several limbs (a floating base, or a fixed base carrying several
arms) is drawn one limb per figure, so each stays readable. The limbs are the kinematic
subtrees below the base: the children of the free-flyer joint (floating base) or of the
universe (fixed base), from the Pinocchio model's ``parents``; the base rows are their own
group. A subtree with more than ``max_rows`` rows is split at its first branching joint
(the chain down to it, then each branch), recursively. A limb is named by the prefix its joints
share (``FL_HAA, FL_HFE, FL_KFE`` → ``FL``), else the one most of them share, else its first joint.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Sequence

__all__ = ["effort_unit", "grouped_paths", "limb_groups", "motion_units"]

BASE_ROWS = {"base_vx": "N", "base_vy": "N", "base_vz": "N", "base_wx": "N·m", "base_wy": "N·m", "base_wz": "N·m"}
#: the unit when nothing says whether a joint is rotary or linear (a friction-only bench model)
UNKNOWN_EFFORT = "N·m or N"


def _revolute(robot, row: str) -> bool | None:
    """True/False for a joint or coordinate of ``robot``; None if it is not one."""
    if robot is None or row not in tuple(getattr(robot, "joint_names", ())):
        return None
    try:
        return bool(robot.is_revolute(row))
    except Exception:  # noqa: BLE001 - a robot-like object without joint types: unknown
        return None


def effort_unit(robot, row: str) -> str:
    """Unit of the generalized force of ``row``: N·m (revolute, base moment), N (prismatic, base
    force), ``"N·m or N"`` when ``robot`` is None or does not know the row."""
    if row in BASE_ROWS:
        return BASE_ROWS[row]
    rev = _revolute(robot, row)
    return UNKNOWN_EFFORT if rev is None else "N·m" if rev else "N"


def motion_units(robot, row: str) -> tuple[str, str, str]:
    """(position, velocity, acceleration) units of a joint: rad, rad/s, rad/s² or m, m/s, m/s²."""
    rev = _revolute(robot, row)
    if rev is None:
        return "rad or m", "rad/s or m/s", "rad/s² or m/s²"
    return ("rad", "rad/s", "rad/s²") if rev else ("m", "m/s", "m/s²")


def limb_groups(robot, rows: Sequence[str], max_rows: int = 12) -> dict[str, list[str]]:
    """``rows`` grouped per limb (module docstring), in the order of ``rows``: ``{name: rows}``.
    One group (named ``""``) when the robot has one limb, is a coupled robot, is None, or
    ``rows`` holds names that are not its joints."""
    rows = list(rows)
    model = getattr(robot, "model", None)
    joints = [r for r in rows if r not in BASE_ROWS]
    if robot is None or model is None or getattr(robot, "coupled", False) or not joints:
        return {"": rows}
    names = list(model.names)
    if any(j not in names for j in joints):
        return {"": rows}
    parents = [int(p) for p in model.parents]
    children: dict[int, list[int]] = {i: [] for i in range(len(names))}
    for i in range(1, len(names)):
        children[parents[i]].append(i)
    root = 1 if getattr(robot, "floating_base", False) else 0
    wanted = {names.index(j) for j in joints}
    groups: list[list[int]] = []
    for child in children[root]:
        _split(child, children, wanted, max_rows, groups)
    rank = {j: k for k, j in enumerate(rows)}
    out: dict[str, list[str]] = {}
    base = [r for r in rows if r in BASE_ROWS]
    if base:
        out["base"] = base
    for g in sorted((g for g in groups if g), key=lambda g: min(rank[names[i]] for i in g)):
        members = sorted((names[i] for i in g), key=rank.__getitem__)
        name, k = _limb_name(members), 2
        while name in out or not name:
            name, k = f"{_limb_name(members) or 'limb'}_{k}", k + 1
        out[name] = members
    if len(out) == 1:
        return {"": rows}
    return out


def _subtree(i: int, children: dict[int, list[int]]) -> list[int]:
    out, stack = [], [i]
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(reversed(children[j]))
    return out


def _split(i: int, children, wanted: set[int], max_rows: int, groups: list[list[int]]) -> None:
    """Append the rows of the subtree at joint ``i`` as one group, or split it at its first branching."""
    members = [j for j in _subtree(i, children) if j in wanted]
    if len(members) <= max_rows:
        groups.append(members)
        return
    chain = [i]
    while len(children[chain[-1]]) == 1:
        chain.append(children[chain[-1]][0])
    if not children[chain[-1]]:  # an unbranched chain longer than max_rows: keep it whole
        groups.append(members)
        return
    groups.append([j for j in chain if j in wanted])
    for c in children[chain[-1]]:
        _split(c, children, wanted, max_rows, groups)


def _limb_name(members: list[str]) -> str:
    """The prefix all the limb's joints share (``FL_HAA, FL_HFE, FL_KFE`` → ``FL``), else the longest one most
    share (``arm_left_1_joint`` … ``arm_left_7_joint``, ``gripper_left_joint`` → ``arm_left``), trailing
    separators dropped; else its first joint."""
    first = members[0]
    if len(members) == 1:
        return first
    def shared(need: int) -> str:
        k = next((k for k in range(len(first), 0, -1) if sum(m.startswith(first[:k]) for m in members) >= need), 0)
        return re.sub(r"[^A-Za-z0-9]+$", "", first[:k])

    return shared(len(members)) or shared(len(members) // 2 + 1) or first


def grouped_paths(out_dir: "str | Path", stem: str, groups: dict[str, list[str]]) -> dict[str, Path]:
    """Figure file per group: ``STEM.png`` for a single group, else ``STEM_<limb>.png`` (the limb name
    with characters other than letters, digits, ``-`` and ``_`` replaced by ``_``)."""
    out_dir = Path(out_dir)
    if len(groups) == 1:
        return {next(iter(groups)): out_dir / f"{stem}.png"}
    return {g: out_dir / f"{stem}_{re.sub(r'[^A-Za-z0-9_-]', '_', g)}.png" for g in groups}

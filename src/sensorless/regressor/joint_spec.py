"""Per-joint settings of a model structure, as users write them: which joint terms each
joint has (``"fv,fc"`` or ``"j1=fv,fc;*=fv"``, :func:`parse_joint_terms`) and per-joint
numbers such as the Coulomb smoothing or the Stribeck velocity (one value, or a mapping with
an optional ``'*'`` for the joints not named). The terms themselves are the registry
:mod:`.joint_terms`.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import RobotModelError, did_you_mean
from .joint_terms import JOINT_TERMS, terms_where

__all__ = ["DEFAULT_STRIBECK_VELOCITY", "PASSIVE_TERMS", "parse_joint_terms", "parse_presliding", "passive_terms"]

#: terms a passive joint (no actuator) can have: its friction (the registry's ``passive`` flag,
#: :mod:`.joint_terms`). No offset (there is no torque sensor to be offset; on a rail along gravity it
#: would be m·g again) and no armature (no rotor).
PASSIVE_TERMS = terms_where("passive")
#: Stribeck velocity vs [rad/s or m/s] of a joint whose vs is not given
DEFAULT_STRIBECK_VELOCITY = 0.1


def parse_joint_terms(spec: "str | Mapping | tuple | list", joints: "tuple[str, ...] | list[str]") -> dict[str, tuple[str, ...]]:
    """Terms per joint from ``"fv,fc"`` (every joint) or ``"j1=fv,fc,offset;j2=fv;*=fv,fc"``
    (``*``: the joints not listed; without it, unlisted joints get no terms), or a mapping
    of the same. RobotModelError names an unknown joint or term."""
    if isinstance(spec, str):
        if "=" not in spec:
            spec = {"*": spec}
        else:
            parts = {}
            for item in spec.split(";"):
                if not item.strip():
                    continue
                name, sep, terms = item.partition("=")
                if not sep:
                    raise RobotModelError(f"joint terms '{item}': expected JOINT=term,term (e.g. 'wrist_3_joint=fv')")
                parts[name.strip()] = terms
            spec = parts
    spec = _by_joint(spec, joints, "joint terms")
    out = {}
    for j in joints:
        terms = spec.get(j, spec.get("*", ()))
        if isinstance(terms, str):
            terms = [t.strip() for t in terms.split(",") if t.strip()]
        bad = [t for t in terms if t not in JOINT_TERMS]
        if bad:
            raise RobotModelError(f"unknown joint term(s) {bad} for '{j}'; choose from {JOINT_TERMS}")
        out[j] = tuple(t for t in JOINT_TERMS if t in terms)
    return out


def named_joints(spec) -> set[str]:
    """Joints a terms spec names explicitly (not through '*' or one list for every joint)."""
    if isinstance(spec, str):
        if "=" not in spec:
            return set()
        return {item.partition("=")[0].strip() for item in spec.split(";") if item.strip()} - {"*"}
    if isinstance(spec, Mapping):
        return set(spec) - {"*"}
    return set()


def passive_terms(per_joint: Mapping[str, tuple[str, ...]], passive, named=()) -> dict[str, tuple[str, ...]]:
    """``per_joint`` with each passive joint's terms cut to :data:`PASSIVE_TERMS`; a passive joint
    ``named`` explicitly with another term is an error (RobotModelError naming it)."""
    out = dict(per_joint)
    for j in passive:
        bad = [t for t in out.get(j, ()) if t not in PASSIVE_TERMS]
        if bad and j in named:
            raise RobotModelError(f"passive joint '{j}' cannot have the term(s) {bad}: it has no actuator (no torque "
                                  f"sensor to be offset, no rotor); a passive joint's terms are {', '.join(PASSIVE_TERMS)}")
        out[j] = tuple(t for t in out.get(j, ()) if t in PASSIVE_TERMS)
    return out


def parse_presliding(value, joints, need) -> "dict | None":
    """{joint: {"k", "play"}} for the joints ``need`` that have it given (a joint without one has its k
    chosen by the identification, :mod:`sensorless.identification.presliding`); RobotModelError on bad values."""
    if not value:
        return None
    out = {}
    for j, p in value.items():
        if j not in joints:
            close = did_you_mean(j, joints)
            raise RobotModelError(f"presliding given for unknown joint '{j}'{f' ({close})' if close else ''}; term joints "
                                  f"are {list(joints)}")
        if j not in need:
            continue
        k, h = (p.get("k"), p.get("play", 0.0)) if isinstance(p, Mapping) else (p, 0.0)
        if not all(isinstance(x, (int, float, np.floating)) and np.isfinite(x) for x in (k, h)) or k <= 0 or h < 0:
            raise RobotModelError(f"presliding of '{j}' needs k > 0 [1/rad] and play >= 0 [rad], got {p!r}")
        out[j] = {"k": float(k), "play": float(h)}
    return out or None


def _by_joint(value, joints, what: str) -> Mapping:
    """``value`` as a mapping {joint or '*': …} ('*' for a single value), checking the joint names."""
    if not isinstance(value, Mapping):
        value = {"*": value}
    unknown = [j for j in value if j != "*" and j not in joints]
    if unknown:
        close = "".join(f"; for '{j}', {h}" for j in unknown if (h := did_you_mean(j, joints)))
        raise RobotModelError(f"{what} names unknown joint(s) {unknown}{close}; actuated joints are {list(joints)}")
    return value


def per_joint_values(value, joints, what: str) -> dict[str, float]:
    """A number for every joint, or a mapping (with optional '*'), as {joint: float >= 0}."""
    if value is None:
        return {}
    value = _by_joint(value, joints, what)
    out = {}
    for j in joints:
        x = value.get(j, value.get("*"))
        if x is None:
            continue
        if isinstance(x, bool) or not isinstance(x, (int, float, np.floating, np.integer)) or not (np.isfinite(x) and x >= 0):
            raise RobotModelError(f"{what} of '{j}' must be a finite number >= 0, got {x!r}")
        out[j] = float(x)
    return out

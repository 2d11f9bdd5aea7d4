"""The registry of joint terms: every per-joint column of the model, one frozen object per file.

A joint term (:class:`~.base.JointTerm`) declares its name, its column and capability flags
(passive joints, motion, acceleration, sign, reversal, history, export); the regressor
(:mod:`sensorless.regressor.terms`), the acceleration-free form (:mod:`..integral`), the
constraints, the identifiability check, the friction curve and the model export read the flags
here instead of listing names. :data:`REGISTRY`'s order is the column order of every joint's
block (labels ``joint.term``), so a new term goes at the end: existing models keep their columns.

To add a term: one file here with its column function and a :class:`~.base.JointTerm` (name,
description, column and the flags that differ from the defaults), one line in :data:`REGISTRY`, one
oracle test (its column against a direct computation, ``tests/test_regressor_joint_terms.py``).
"""

from __future__ import annotations

from .armature import ARMATURE
from .base import JointTerm, TermInputs
from .coulomb import COULOMB
from .offset import OFFSET
from .presliding import PRESLIDING
from .stribeck import STRIBECK
from .viscous import VISCOUS
from .viscous_asymmetry import VISCOUS_ASYMMETRY

__all__ = ["JOINT_TERMS", "JointTerm", "REGISTRY", "TermInputs", "joint_term", "terms_where"]

REGISTRY: tuple[JointTerm, ...] = (
    VISCOUS,
    COULOMB,
    STRIBECK,
    OFFSET,
    ARMATURE,
    PRESLIDING,
    VISCOUS_ASYMMETRY,
)
#: the term names, in column order
JOINT_TERMS: tuple[str, ...] = tuple(t.name for t in REGISTRY)
_BY_NAME = {t.name: t for t in REGISTRY}


def joint_term(name: str) -> JointTerm:
    """The registered term ``name`` (KeyError for an unknown one: names are checked where users give them,
    :func:`~sensorless.regressor.joint_spec.parse_joint_terms`)."""
    return _BY_NAME[name]


def terms_where(flag: str, value: bool = True) -> tuple[str, ...]:
    """Names of the terms whose capability ``flag`` is ``value``, in column order."""
    return tuple(t.name for t in REGISTRY if getattr(t, flag) is value)

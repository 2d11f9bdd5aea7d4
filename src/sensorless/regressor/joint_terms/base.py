"""What a joint term is: one column per term joint, and what the rest of the package needs to know
about it (capability flags), as :mod:`..rowmap` does for row maps.

A joint term adds φ_j c(v_j, v̇_j, s_j) to the equation of term joint j (one parameter φ_j per joint;
:mod:`sensorless.regressor.terms`). The column c is computed from :class:`TermInputs`, the per-joint
signals every term shares (velocity, acceleration, the Coulomb and sliding signs, the Stribeck
velocity, the presliding state). The flags tell the other modules what to do with the term, so that
none of them lists term names:

* ``passive``: a joint without an actuator may have it (friction; no offset, no rotor inertia);
* ``needs_motion``: unidentifiable on a joint that does not move (:mod:`~sensorless.identification.uncertainty`);
* ``acceleration``: the column is v̇ (the momentum column v in the acceleration-free form,
  :mod:`..integral`; 0 in a friction curve v ↦ τ_f, :func:`~sensorless.identification.friction.friction_curve`);
* ``nonnegative``: φ ≥ 0 in a physically consistent fit (:mod:`~sensorless.identification.constraints`);
* ``reversal``: the column jumps when v changes sign, so the equations at a velocity reversal are left
  out of the fit (:func:`..friction_columns.fit_keep`);
* ``stateful``: the column depends on the history of q (whole logs, not chunks); its steady value
  while sliding at constant velocity is sgn v;
* ``exported``: the value is written to ``joint_terms.json`` (else it lives in ``result.json`` only).

A new term is unexported by default: ``joint_terms.json`` has a fixed set of fields
(:class:`sensorless.parameters.JointTerms`).
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from functools import cached_property
from typing import Callable

import numpy as np

from ..friction_columns import coulomb_sign, sliding_sign

__all__ = ["JointTerm", "TermInputs"]


class TermInputs:
    """Per-joint signals of N samples and n term joints that the columns are made of.

    ``v``, ``a`` (N, n) velocities and accelerations; ``eps`` (n,) Coulomb transition widths ε
    (0: sgn); ``rest`` (n,) rest velocities δ; ``vs`` (n,) Stribeck velocities; ``friction_law``
    ("blend" or "product", :mod:`.stribeck`); ``z`` (N, n) presliding states or None.
    """

    def __init__(self, v, a, eps, rest, vs, friction_law: str = "blend", z=None) -> None:
        self.v, self.a, self.eps, self.rest, self.vs = v, a, eps, rest, vs
        self.friction_law, self.z = friction_law, z

    @cached_property
    def coulomb_sign(self) -> np.ndarray:
        """T = tanh(v/ε) (sgn v for ε = 0), 0 where |v| ≤ δ (:func:`..friction_columns.coulomb_sign`)."""
        return coulomb_sign(self.v, self.eps, self.rest)

    @cached_property
    def sliding_sign(self) -> np.ndarray:
        """sgn v, 0 where |v| ≤ δ (:func:`..friction_columns.sliding_sign`)."""
        return sliding_sign(self.v, self.rest)


@dataclass(frozen=True)
class JointTerm:
    """One joint term: its ``name`` (the parameter label ``joint.name``), a one-line ``description``, its
    ``column`` (:class:`TermInputs` → the column per term joint, shape (N, n)) and the capability flags of
    the module docstring. The flags default to a term of actuated joints only that needs motion, is
    memoryless, sign-free, continuous at a reversal and lives in result.json only; a term states the
    flags that differ."""

    name: str
    description: str
    column: Callable[[TermInputs], np.ndarray]
    _: KW_ONLY
    passive: bool = False
    needs_motion: bool = True
    acceleration: bool = False
    nonnegative: bool = False
    reversal: bool = False
    stateful: bool = False
    exported: bool = False

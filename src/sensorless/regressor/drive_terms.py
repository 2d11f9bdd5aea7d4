"""Drive terms: friction, motor inertia and springs on linear coordinates of the drives.

A *drive coordinate* is a linear combination of the independent (motor) coordinates θ,

    s = gᵀ θ + s₀,   ṡ = gᵀ θ̇,   s̈ = gᵀ θ̈.

It is a motor shaft (g = unit vector), a joint driven through a coupling (a row of the
coupling matrix) or a relative motion such as a jaw opening (difference of two rows).
The generalised force acting along s is linear in the parameters,

    f = fv ṡ + fc sgn(ṡ) + offset + inertia s̈ + k (s − s_rest)
      = [ṡ, sgn ṡ, 1, s̈, s, −1] · [fv, fc, offset, inertia, k, k·s_rest],

and, by virtual work (f ṡ = τ_θᵀ θ̇), it adds τ_θ += g f to the equations of the
independent coordinates. ``sgn`` is ``tanh(ṡ / ε)`` when a smoothing velocity ε > 0 is
given (per drive, or one value for the whole structure). The spring's rest term ``k·s_rest`` multiplies a constant, like ``offset``: the two
are one base parameter when both are enabled.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import RobotModelError

__all__ = ["DRIVE_TERMS", "DriveTerm", "drive_parameter_names"]

DRIVE_TERMS = ("fv", "fc", "offset", "inertia", "spring")
_PARAMS = {"fv": ("fv",), "fc": ("fc",), "offset": ("offset",), "inertia": ("inertia",), "spring": ("k", "k_rest")}


def drive_parameter_names(terms: Sequence[str]) -> list[str]:
    """Parameter names of the enabled terms, in :data:`DRIVE_TERMS` order."""
    return [p for t in DRIVE_TERMS if t in terms for p in _PARAMS[t]]


@dataclass(frozen=True)
class DriveTerm:
    """Terms acting on one drive coordinate ``s = gᵀθ + s0`` (see module docstring).

    ``g`` has one entry per independent coordinate. ``terms`` is a subset of
    :data:`DRIVE_TERMS`; parameters are named ``"{name}.{p}"`` with ``p`` in
    fv, fc, offset, inertia, k, k_rest.
    """

    name: str
    g: np.ndarray
    terms: tuple[str, ...] = ("fv", "fc", "offset")
    s0: float = 0.0
    smoothing: float | None = None  # Coulomb smoothing velocity ε of this drive (None: the structure's)
    param_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        g = np.asarray(self.g, dtype=float).ravel()
        if g.size == 0 or not np.all(np.isfinite(g)) or not np.any(g):
            raise RobotModelError(f"drive '{self.name}': g must be a finite, non-zero vector, got {self.g!r}")
        bad = [t for t in self.terms if t not in DRIVE_TERMS]
        if bad:
            raise RobotModelError(f"drive '{self.name}': unknown term(s) {bad}; choose from {DRIVE_TERMS}")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "terms", tuple(t for t in DRIVE_TERMS if t in self.terms))
        object.__setattr__(self, "param_names", tuple(drive_parameter_names(self.terms)))

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def labels(self) -> list[str]:
        return [f"{self.name}.{p}" for p in self.param_names]

    def coordinate(self, theta: np.ndarray) -> np.ndarray:
        """s = θ g + s0 for θ of shape (N, n)."""
        return np.asarray(theta) @ self.g + self.s0

    def features(self, theta: np.ndarray, dtheta: np.ndarray, ddtheta: np.ndarray, coulomb_smoothing: float = 0.0) -> np.ndarray:
        """Feature columns of the generalised force on s, shape (N, n_params). The drive's own
        ``smoothing`` overrides ``coulomb_smoothing`` when set."""
        if self.smoothing is not None:
            coulomb_smoothing = self.smoothing
        sd = np.asarray(dtheta) @ self.g
        cols: list[np.ndarray] = []
        for t in self.terms:
            if t == "fv":
                cols.append(sd)
            elif t == "fc":
                cols.append(np.sign(sd) if coulomb_smoothing <= 0 else np.tanh(sd / coulomb_smoothing))
            elif t == "offset":
                cols.append(np.ones_like(sd))
            elif t == "inertia":
                cols.append(np.asarray(ddtheta) @ self.g)
            else:  # spring: k s − k s_rest
                cols.append(self.coordinate(theta))
                cols.append(-np.ones_like(sd))
        return np.stack(cols, axis=1) if cols else np.zeros((sd.shape[0], 0))

    def force(self, values: dict[str, float], theta, dtheta, ddtheta, coulomb_smoothing: float = 0.0) -> np.ndarray:
        """Generalised force f along s for named parameter values (missing names = 0)."""
        x = np.array([values.get(p, 0.0) for p in self.param_names])
        return self.features(theta, dtheta, ddtheta, coulomb_smoothing) @ x

    def to_dict(self) -> dict:
        return {"name": self.name, "g": self.g.tolist(), "terms": list(self.terms), "s0": self.s0, "smoothing": self.smoothing}

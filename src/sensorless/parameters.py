"""Inertial parameters: conventions, changes of coordinates and physical consistency.

Convention
----------
Per body, the 10 dynamic parameters are Pinocchio's (``pin.Inertia.toDynamicParameters()``)::

    pi = [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]

with ``c`` the centre of mass and ``I`` the rotational inertia about the JOINT frame
origin (not the CoM), both expressed in the joint frame. A robot's vector stacks its
bodies in Pinocchio joint order (``model.inertias[1:]``), 10 entries per body. Every
function here takes arrays of shape ``(..., 10)`` (a stacked ``(10 n,)`` vector is
accepted where noted) and works on all leading dimensions at once.

Pseudo-inertia (Wensing, Kim & Slotine 2017)::

    J = [[Sigma, h], [h^T, m]],   Sigma = 1/2 tr(I) 1 - I,   h = m c

``J`` is linear in ``pi`` (``J = sum_i pi_i A_i``, :func:`pseudo_inertia_basis`). A body
is *physically consistent* (some non-negative mass density produces it) iff ``J >= 0``;
for ``m > 0`` this is equivalent to the triangle inequalities on the principal moments
about the CoM. A massless body whose parameters are all zero has ``J = 0``, which is
PSD, so it counts as consistent (e.g. a massless root link).

Log-Cholesky (Rucker & Wensing 2022), ``theta = [alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3]``::

    J = exp(2 alpha) U U^T,  U = [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]

an unconstrained chart of the positive-definite bodies (same ordering as
``pin.LogCholeskyParameters``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import pinocchio as pin

from .errors import ParameterError, PhysicalConsistencyError

__all__ = [
    "PARAMETER_NAMES",
    "TERM_NAMES",
    "FRICTION_LAW_NAMES",
    "parameter_labels",
    "as_bodies",
    "inertia_matrix",
    "pin_inertia",
    "pseudo_inertia",
    "from_pseudo_inertia",
    "pseudo_inertia_basis",
    "log_cholesky",
    "from_log_cholesky",
    "com_frame",
    "from_com_frame",
    "urdf_inertial",
    "from_urdf_inertial",
    "ConsistencyReport",
    "check_physical_consistency",
    "is_physically_consistent",
    "JointTerms",
]

PARAMETER_NAMES: tuple[str, ...] = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
TERM_NAMES: tuple[str, ...] = ("fv", "fc", "offset", "armature")
#: optional per-joint friction-law terms of :class:`JointTerms` (written only where non-zero)
FRICTION_LAW_NAMES: tuple[str, ...] = ("stribeck", "stribeck_velocity", "coulomb_smoothing")

# index of I[r, c] in pi
_I_IDX = np.array([[4, 5, 7], [5, 6, 8], [7, 8, 9]])
_ROWS, _COLS = np.array([0, 0, 1, 0, 1, 2]), np.array([0, 1, 1, 2, 2, 2])  # Ixx Ixy Iyy Ixz Iyz Izz


def parameter_labels(body_names: Sequence[str]) -> list[str]:
    """``["<body>.m", "<body>.mx", ...]`` for every body, in vector order."""
    return [f"{b}.{p}" for b in body_names for p in PARAMETER_NAMES]


def as_bodies(pi: np.ndarray) -> np.ndarray:
    """``(n, 10)`` view of a stacked ``(10 n,)`` vector; ``(..., 10)`` arrays pass through."""
    pi = np.asarray(pi, dtype=float)
    if pi.ndim == 1:
        if pi.size % 10:
            raise ParameterError(f"a parameter vector needs 10 entries per body, got {pi.size}")
        return pi.reshape(-1, 10)
    if pi.shape[-1] != 10:
        raise ParameterError(f"expected parameters of shape (..., 10), got {pi.shape}")
    return pi


def _check10(pi: np.ndarray) -> np.ndarray:
    pi = np.asarray(pi, dtype=float)
    if pi.shape[-1:] != (10,):
        raise ParameterError(f"expected parameters of shape (..., 10), got {pi.shape}")
    return pi


def inertia_matrix(pi: np.ndarray) -> np.ndarray:
    """Rotational inertia about the joint origin, ``(..., 3, 3)``."""
    return _check10(pi)[..., _I_IDX]


def _sym6(M: np.ndarray) -> np.ndarray:
    """Upper triangle of symmetric ``(..., 3, 3)`` in the order xx xy yy xz yz zz."""
    return M[..., _ROWS, _COLS]


def _skew_sq(c: np.ndarray) -> np.ndarray:
    """``|c|^2 1 - c c^T`` (the parallel-axis term per unit mass)."""
    return np.einsum("...i,...i->...", c, c)[..., None, None] * np.eye(3) - c[..., :, None] * c[..., None, :]


# ---- pseudo-inertia ----------------------------------------------------------
def pin_inertia(pi: np.ndarray) -> pin.Inertia:
    """``pin.Inertia`` of one body's 10 parameters. Unlike ``Inertia.FromDynamicParameters``
    (c = h/m: NaN for m = 0), a massless body is the zero spatial inertia plus its rotational
    inertia (a massless link, a virtual frame): no NaN enters the dynamics."""
    pi = _check10(pi)
    if pi[0] > 0:
        return pin.Inertia.FromDynamicParameters(pi)
    return pin.Inertia(0.0, np.zeros(3), inertia_matrix(pi))


def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """``J = [[1/2 tr(I) 1 - I, h], [h^T, m]]``, shape ``(..., 4, 4)``."""
    pi = _check10(pi)
    I = inertia_matrix(pi)
    J = np.zeros(pi.shape[:-1] + (4, 4))
    J[..., :3, :3] = 0.5 * np.trace(I, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - I
    J[..., :3, 3] = pi[..., 1:4]
    J[..., 3, :3] = pi[..., 1:4]
    J[..., 3, 3] = pi[..., 0]
    return J


def from_pseudo_inertia(J: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pseudo_inertia` (``J`` is symmetrised): ``I = tr(Sigma) 1 - Sigma``."""
    J = np.asarray(J, dtype=float)
    if J.shape[-2:] != (4, 4):
        raise ParameterError(f"expected pseudo-inertias of shape (..., 4, 4), got {J.shape}")
    J = 0.5 * (J + np.swapaxes(J, -1, -2))
    S = J[..., :3, :3]
    I = np.trace(S, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - S
    return np.concatenate([J[..., 3, 3:4], J[..., :3, 3], _sym6(I)], axis=-1)


def pseudo_inertia_basis() -> np.ndarray:
    """``A`` of shape ``(10, 4, 4)`` with ``pseudo_inertia(pi) == einsum("i,ijk", pi, A)``."""
    return pseudo_inertia(np.eye(10))


# ---- log-Cholesky ------------------------------------------------------------
def log_cholesky(pi: np.ndarray) -> np.ndarray:
    """Log-Cholesky coordinates ``theta (..., 10)`` of positive-definite bodies.

    Raises :class:`PhysicalConsistencyError` if some ``J`` is not positive definite.
    """
    J = pseudo_inertia(pi)
    lead = J.shape[:-2]
    Jf = J.reshape(-1, 4, 4)
    bad = np.flatnonzero(np.linalg.eigvalsh(Jf)[:, 0] <= 0)
    if bad.size:
        where = [tuple(int(i) for i in np.unravel_index(b, lead)) if lead else () for b in bad[:10]]
        raise PhysicalConsistencyError(
            f"log-Cholesky coordinates need a positive-definite pseudo-inertia; "
            f"{bad.size} body(ies) are not (indices {where}{'...' if bad.size > 10 else ''})"
        )
    # Upper-triangular U with U U^T = J: reverse rows/cols, lower Cholesky, reverse back.
    L = np.linalg.cholesky(Jf[:, ::-1, ::-1])
    U = L[:, ::-1, ::-1]
    u33 = U[:, 3, 3]
    Ub = U / u33[:, None, None]
    theta = np.stack(
        [
            np.log(u33),
            np.log(Ub[:, 0, 0]),
            np.log(Ub[:, 1, 1]),
            np.log(Ub[:, 2, 2]),
            Ub[:, 0, 1],
            Ub[:, 1, 2],
            Ub[:, 0, 2],
            Ub[:, 0, 3],
            Ub[:, 1, 3],
            Ub[:, 2, 3],
        ],
        axis=-1,
    )
    return theta.reshape(lead + (10,))


def from_log_cholesky(theta: np.ndarray) -> np.ndarray:
    """Dynamic parameters ``(..., 10)`` from log-Cholesky coordinates (always consistent)."""
    th = _check10(theta)
    U = np.zeros(th.shape[:-1] + (4, 4))
    U[..., 0, 0], U[..., 1, 1], U[..., 2, 2] = np.exp(th[..., 1]), np.exp(th[..., 2]), np.exp(th[..., 3])
    U[..., 0, 1], U[..., 1, 2], U[..., 0, 2] = th[..., 4], th[..., 5], th[..., 6]
    U[..., :3, 3] = th[..., 7:10]
    U[..., 3, 3] = 1.0
    J = np.exp(2.0 * th[..., 0])[..., None, None] * (U @ np.swapaxes(U, -1, -2))
    return from_pseudo_inertia(J)


# ---- CoM frame and URDF ------------------------------------------------------
def com_frame(pi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(m, c, I_C)``: mass, CoM ``(..., 3)`` and inertia about the CoM ``(..., 3, 3)``.

    ``I_C = I - m (|c|^2 1 - c c^T)`` (parallel-axis theorem), joint-frame axes.
    Where ``m == 0`` the CoM is undefined and returned as 0 (so ``I_C = I``).
    """
    pi = _check10(pi)
    m = pi[..., 0]
    safe = np.where(m == 0.0, 1.0, m)
    c = np.where((m == 0.0)[..., None], 0.0, pi[..., 1:4] / safe[..., None])
    I_c = inertia_matrix(pi) - m[..., None, None] * _skew_sq(c)
    return m, c, I_c


def from_com_frame(mass: np.ndarray | float, com: np.ndarray, I_com: np.ndarray) -> np.ndarray:
    """Inverse of :func:`com_frame`: ``pi (..., 10)`` from mass, CoM and CoM inertia."""
    m = np.asarray(mass, dtype=float)
    c = np.asarray(com, dtype=float)
    I_c = np.asarray(I_com, dtype=float)
    I = 0.5 * (I_c + np.swapaxes(I_c, -1, -2)) + m[..., None, None] * _skew_sq(c)
    return np.concatenate([m[..., None], m[..., None] * c, _sym6(I)], axis=-1)


def urdf_inertial(pi: np.ndarray, frame: pin.SE3 | None = None) -> dict[str, Any]:
    """URDF ``<inertial>`` of one body: ``{mass, xyz, ixx, ixy, ixz, iyy, iyz, izz}``.

    ``xyz`` is the CoM and ``i**`` the inertia about the CoM, both in the URDF link
    frame, with ``rpy = 0``. ``frame`` is the placement of that link frame in the joint
    frame (default: identity, i.e. the link frame is the joint frame).
    """
    pi = _check10(pi)
    if pi.shape != (10,):
        raise ParameterError(f"urdf_inertial takes one body (10,), got {pi.shape}")
    m, c, I_c = com_frame(pi)
    if frame is not None:
        R = frame.rotation
        c = R.T @ (c - frame.translation)
        I_c = R.T @ I_c @ R
    return {
        "mass": float(m),
        "xyz": [float(x) for x in c],
        "ixx": float(I_c[0, 0]),
        "ixy": float(I_c[0, 1]),
        "ixz": float(I_c[0, 2]),
        "iyy": float(I_c[1, 1]),
        "iyz": float(I_c[1, 2]),
        "izz": float(I_c[2, 2]),
    }


def from_urdf_inertial(inertial: Mapping[str, Any], frame: pin.SE3 | None = None) -> np.ndarray:
    """``pi (10,)`` from a URDF inertial dict (as :func:`urdf_inertial`; optional ``rpy``)."""
    def g(k: str) -> float:
        try:
            v = float(inertial.get(k, 0.0))
        except (TypeError, ValueError):
            raise ParameterError(f"inertial '{k}' is not a number: {inertial.get(k)!r}") from None
        if not np.isfinite(v):
            raise ParameterError(f"inertial '{k}' is not finite: {v!r}")
        return v

    I = np.array(
        [[g("ixx"), g("ixy"), g("ixz")], [g("ixy"), g("iyy"), g("iyz")], [g("ixz"), g("iyz"), g("izz")]]
    )
    c = np.asarray(inertial.get("xyz", (0.0, 0.0, 0.0)), dtype=float)
    rpy = np.asarray(inertial.get("rpy", (0.0, 0.0, 0.0)), dtype=float)
    if np.any(rpy != 0.0):  # principal-axes frame -> link frame
        R = pin.rpy.rpyToMatrix(rpy)
        I = R @ I @ R.T
    if frame is not None:
        R = frame.rotation
        c = R @ c + frame.translation
        I = R @ I @ R.T
    return from_com_frame(g("mass"), c, I)


# ---- physical consistency ----------------------------------------------------
@dataclass
class ConsistencyReport:
    """Consistency of one body.

    ``principal_moments`` are the eigenvalues of the CoM inertia (ascending);
    ``triangle_margin = min over cyclic (I1 + I2 - I3)`` (>= 0 for a real body, equal to
    twice the smallest eigenvalue of ``Sigma_C``); ``consistent`` means the pseudo-inertia
    is PSD up to ``tol * max(1, ||J||_2)``.
    """

    name: str
    mass: float
    com: np.ndarray
    principal_moments: np.ndarray
    triangle_margin: float
    min_eig_pseudo_inertia: float
    consistent: bool


def _pseudo_min_eig(pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    eig = np.linalg.eigvalsh(pseudo_inertia(pi))
    return eig[..., 0], np.abs(eig).max(axis=-1)


def check_physical_consistency(
    pi: np.ndarray, body_names: Sequence[str] | None = None, tol: float = 1e-9
) -> list[ConsistencyReport]:
    """One :class:`ConsistencyReport` per body of ``pi`` (stacked ``(10 n,)`` or ``(n, 10)``)."""
    P = as_bodies(pi).reshape(-1, 10)
    names = list(body_names) if body_names is not None else [f"body{k}" for k in range(len(P))]
    if len(names) != len(P):
        raise ParameterError(f"{len(names)} body names for {len(P)} bodies")
    m, c, I_c = com_frame(P)
    moments = np.linalg.eigvalsh(I_c)
    tri = (moments.sum(axis=-1)[:, None] - 2.0 * moments).min(axis=-1)  # I1+I2-I3 minimal for the largest I3
    lam, norm = _pseudo_min_eig(P)
    ok = lam >= -tol * np.maximum(1.0, norm)
    return [
        ConsistencyReport(names[k], float(m[k]), c[k], moments[k], float(tri[k]), float(lam[k]), bool(ok[k]))
        for k in range(len(P))
    ]


def is_physically_consistent(pi: np.ndarray, tol: float = 1e-9) -> bool:
    """True if every body's pseudo-inertia eigenvalues are ``>= -tol * max(1, ||J||_2)``."""
    lam, norm = _pseudo_min_eig(as_bodies(pi))
    return bool(np.all(lam >= -tol * np.maximum(1.0, norm)))


# ---- joint terms -------------------------------------------------------------
@dataclass
class JointTerms:
    """Per actuated joint: viscous ``fv`` and Coulomb ``fc`` friction, torque ``offset`` and rotor
    ``armature``, and the optional friction-law terms ``stribeck`` (fs − fc), ``stribeck_velocity``
    vs and ``coulomb_smoothing`` (the transition width w; 0: none / sgn), i.e.
    ``tau = ... + fv qd + fc s + stribeck (s - (1 - exp(-(qd/vs)^2)) sign(qd)) + offset + armature qdd``,
    s = tanh(qd/w) (sign(qd) for w = 0; :mod:`sensorless.regressor.terms`)."""

    joint_names: tuple[str, ...]
    fv: np.ndarray = field(default=None)  # type: ignore[assignment]
    fc: np.ndarray = field(default=None)  # type: ignore[assignment]
    offset: np.ndarray = field(default=None)  # type: ignore[assignment]
    armature: np.ndarray = field(default=None)  # type: ignore[assignment]
    stribeck: np.ndarray = field(default=None)  # type: ignore[assignment]
    stribeck_velocity: np.ndarray = field(default=None)  # type: ignore[assignment]
    coulomb_smoothing: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        self.joint_names = tuple(self.joint_names)
        n = len(self.joint_names)
        for t in TERM_NAMES + FRICTION_LAW_NAMES:
            v = getattr(self, t)
            v = np.zeros(n) if v is None else np.array(v, dtype=float).reshape(-1)
            if v.shape != (n,):
                raise ParameterError(f"JointTerms.{t} has {v.size} values for {n} joints")
            setattr(self, t, v)

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{joint: {"fv": ..., "fc": ..., "offset": ..., "armature": ...}}``, plus the friction-law
        terms of a joint where they are non-zero."""
        return {j: {t: float(getattr(self, t)[k]) for t in TERM_NAMES}
                | {t: float(getattr(self, t)[k]) for t in FRICTION_LAW_NAMES if getattr(self, t)[k] != 0}
                for k, j in enumerate(self.joint_names)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Mapping[str, float]]) -> "JointTerms":
        """Inverse of :meth:`to_dict`; missing terms default to 0, unknown ones are an error."""
        names = tuple(d)
        known = TERM_NAMES + FRICTION_LAW_NAMES
        for j in names:
            unknown = set(d[j]) - set(known)
            if unknown:
                raise ParameterError(f"joint '{j}': unknown term(s) {sorted(unknown)}; expected {known}")
        try:
            vals = {t: [float(d[j].get(t, 0.0)) for j in names] for t in known}
        except (TypeError, ValueError, AttributeError) as exc:
            raise ParameterError(f"joint terms must map joint -> {{term: number}} ({exc})") from None
        bad = [f"{j}.{t}" for t in known for j, v in zip(names, vals[t]) if not np.isfinite(v)]
        if bad:
            raise ParameterError(f"joint terms {bad[:5]} are not finite")
        return cls(names, **vals)

"""Payload identification from the torque residual of an identified robot model.

A payload rigidly fixed to frame f is one more body. Its 10 parameters
φ = [m, m c, I_f] (Pinocchio order, inertia about the frame origin, in frame axes) enter
the joint torques linearly:

    τ − W(q, q̇, q̈) π̂  ≈  J_f(q)ᵀ Φ_f(q, q̇, q̈) φ  =  Y_p φ

with π̂ the identified robot parameters, Φ_f Pinocchio's body regressor of a body at the
frame (``pin.frameBodyRegressor``, after ``pin.rnea`` so gravity is included) and J_f the
frame Jacobian in the LOCAL frame. The payload is then fitted to the residual:

* ``mode="full"``: all 10 parameters, weighted least squares; if the solution is not
  physically consistent, the convex problem min ‖L(Y_p φ − r)‖² s.t. pseudo-inertia
  J(φ) ⪰ 0 is solved with cvxpy + Clarabel (a small SDP).
* ``mode="com"``: mass and centre of mass only, the payload taken as a point mass
  (I_f = m S(c), iterated on c) — for data that does not excite its rotational inertia.
* ``mode="mass"``: mass only, the CoM given (default: the frame origin).
* ``mode="auto"``: "full" if the inertia columns are excited (see ``inertia_threshold``),
  else "com".

Rows are weighted by the inverse residual variance per joint (two-step, as in WLS).
Uncertainty: the analytic standard error (Yᵀ Σ⁻¹ Y)⁻¹ assumes white residuals and is
optimistic for time series; a block bootstrap (non-overlapping blocks of ``block_seconds``
resampled with replacement, re-solved with the same estimator) is reported alongside and
used for ``mass_std``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import DataError, ExcitationError, SolverError
from ..parameters import pseudo_inertia, pseudo_inertia_basis
from ..regressor.compress import iter_trajectories
from ..regressor.terms import ModelStructure
from ..robot import Robot

__all__ = ["PayloadEstimate", "identify_payload", "payload_regressor", "point_mass_parameters"]

MODES = ("auto", "full", "com", "mass")


def payload_regressor(robot: Robot, Q: np.ndarray, V: np.ndarray, A: np.ndarray, frame: str) -> np.ndarray:
    """Y_p (N, n_actuated, 10): actuated joint torques per unit payload parameter at ``frame``."""
    fid = robot.frame_id(frame)
    model, data = robot.model, robot.data
    act = robot.actuated_v_indices
    out = np.empty((Q.shape[0], len(act), 10))
    for i in range(Q.shape[0]):
        pin.rnea(model, data, Q[i], V[i], A[i])
        Phi = pin.frameBodyRegressor(model, data, fid).copy()
        J = pin.computeFrameJacobian(model, data, Q[i], fid, pin.LOCAL)
        out[i] = (J.T @ Phi)[act]
    return out


def _skew_sq(c: np.ndarray) -> np.ndarray:
    return (c @ c) * np.eye(3) - np.outer(c, c)


def point_mass_parameters(mass: float, com: np.ndarray) -> np.ndarray:
    """φ of a point mass at ``com`` (frame coordinates): [m, m c, m S(c)], S(c) = |c|² 1 − c cᵀ."""
    com = np.asarray(com, dtype=float)
    I = mass * _skew_sq(com)
    return np.concatenate([[mass], mass * com, [I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]]])


@dataclass
class PayloadEstimate:
    """Identified payload at ``frame``; ``parameters`` in Pinocchio order (frame axes)."""

    frame: str
    mode: str
    parameters: np.ndarray
    mass_std: float
    mass_std_analytic: float
    mass_std_bootstrap: float | None
    com_std: np.ndarray | None
    consistent: bool
    min_pseudo_inertia_eig: float
    residual_rms_before: np.ndarray
    residual_rms_after: np.ndarray
    joints: list[str]
    n_samples: int
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)

    @property
    def mass(self) -> float:
        return float(self.parameters[0])

    @property
    def com(self) -> np.ndarray:
        m = self.mass
        return self.parameters[1:4] / m if m > 0 else np.full(3, np.nan)

    @property
    def inertia_com(self) -> np.ndarray:
        """Rotational inertia about the CoM (frame axes)."""
        p = self.parameters
        I = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
        return I - self.mass * _skew_sq(self.com) if self.mass > 0 else I

    def __str__(self) -> str:
        c = ", ".join(f"{x * 1e3:.1f}" for x in self.com)
        return f"payload at '{self.frame}': m = {self.mass:.4f} ± {self.mass_std:.4f} kg, CoM = ({c}) mm [{self.mode}]"

    def to_dict(self) -> dict:
        return {
            "frame": self.frame, "mode": self.mode, "mass": self.mass, "mass_std": self.mass_std,
            "mass_std_analytic": self.mass_std_analytic, "mass_std_bootstrap": self.mass_std_bootstrap,
            "com": self.com.tolist(), "com_std": None if self.com_std is None else self.com_std.tolist(),
            "inertia_com": self.inertia_com.tolist(), "parameters": self.parameters.tolist(),
            "consistent": self.consistent, "min_pseudo_inertia_eig": self.min_pseudo_inertia_eig,
            "residual_rms_before": dict(zip(self.joints, self.residual_rms_before.tolist())),
            "residual_rms_after": dict(zip(self.joints, self.residual_rms_after.tolist())),
            "n_samples": self.n_samples, "settings": self.settings, "diagnostics": self.diagnostics,
        }


def _unpack_model(model) -> tuple[ModelStructure, np.ndarray]:
    if isinstance(model, tuple) and len(model) == 2:
        return model[0], np.asarray(model[1], dtype=float)
    for s_attr, p_attr in (("structure", "parameters"), ("structure_", "parameters_")):
        if hasattr(model, s_attr) and hasattr(model, p_attr):
            return getattr(model, s_attr), np.asarray(getattr(model, p_attr), dtype=float)
    raise DataError("model must be an IdentificationResult, a fitted PhysicalModel or a (structure, parameters) pair")


class _Blocks:
    """Per-block, per-row normal equations of Y_p φ ≈ r (10 columns)."""

    def __init__(self, rows: int) -> None:
        self.A: list[np.ndarray] = []  # (rows, 10, 10) per block
        self.b: list[np.ndarray] = []  # (rows, 10)
        self.c: list[np.ndarray] = []  # (rows,)
        self.n: list[int] = []
        self.rows = rows

    def add(self, Y: np.ndarray, r: np.ndarray) -> None:
        Yt = Y.transpose(1, 0, 2)  # (rows, n, 10)
        self.A.append(np.einsum("rni,rnj->rij", Yt, Yt))
        self.b.append(np.einsum("rni,nr->ri", Yt, r))
        self.c.append(np.einsum("nr,nr->r", r, r))
        self.n.append(Y.shape[0])

    def total(self, idx: np.ndarray | None = None):
        sel = range(len(self.A)) if idx is None else idx
        A = sum(self.A[i] for i in sel)
        b = sum(self.b[i] for i in sel)
        c = sum(self.c[i] for i in sel)
        n = sum(self.n[i] for i in sel)
        return A, b, c, n


class _Solver:
    """The estimator of one mode on weighted normal equations (A 10×10, b 10)."""

    def __init__(self, mode: str, consistent: bool, com: np.ndarray | None) -> None:
        self.mode, self.consistent, self.com = mode, consistent, com
        self._basis = pseudo_inertia_basis()

    def __call__(self, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (φ, covariance-like inverse of the used normal matrix, in φ coordinates)."""
        if self.mode == "mass":
            g = point_mass_parameters(1.0, self.com)
            a, bb = float(g @ A @ g), float(g @ b)
            if a <= 0:
                raise ExcitationError("the payload mass is not excited by this log (zero regressor)")
            m = max(bb / a, 0.0)
            return m * g, np.outer(g, g) / a
        if self.mode == "com":
            c = np.zeros(3)
            for _ in range(10):
                G = np.zeros((10, 4))  # φ = G [m, h]: inertia of a point mass at the current c
                G[0, 0] = 1.0
                G[1:4, 1:4] = np.eye(3)
                G[4:, 0] = point_mass_parameters(1.0, c)[4:]
                Ar, br = G.T @ A @ G, G.T @ b
                x = _solve_spd(Ar, br)
                if x[0] <= 0:
                    x = np.zeros(4)
                c_new = x[1:4] / x[0] if x[0] > 0 else np.zeros(3)
                if np.allclose(c_new, c, atol=1e-9):
                    break
                c = c_new
            phi = point_mass_parameters(x[0], c) if x[0] > 0 else np.zeros(10)
            return phi, G @ np.linalg.pinv(Ar) @ G.T
        phi = _solve_spd(A, b)
        cov = np.linalg.pinv(A)
        if self.consistent and np.linalg.eigvalsh(pseudo_inertia(phi))[0] < 0:
            phi = self._sdp(A, b)
        return phi, cov

    def _sdp(self, A: np.ndarray, b: np.ndarray) -> np.ndarray:
        import cvxpy as cp

        # equilibrate columns (x = s ⊙ φ) and normalise the data (y = x / κ): the pseudo-inertia
        # constraint is homogeneous, so the minimiser scales back exactly
        s = np.sqrt(np.maximum(np.diag(A), 1e-300))
        As = A / np.outer(s, s)
        L = np.linalg.cholesky(As + 1e-12 * np.trace(As) / 10 * np.eye(10))
        z = np.linalg.solve(L, b / s)
        kappa = max(float(np.linalg.norm(z)), 1e-300)
        x = cp.Variable(10)
        P = cp.Variable((4, 4), PSD=True)
        phi = cp.multiply(1.0 / s, x)
        scale = 1.0 / max(float(np.max(np.abs(self._basis.reshape(10, -1)).max(1) / s)), 1e-300)
        J = sum((scale * phi[i]) * self._basis[i] for i in range(10))
        prob = cp.Problem(cp.Minimize(cp.sum_squares(L.T @ x - z / kappa)), [P == J])
        try:
            prob.solve(solver=cp.CLARABEL)
        except cp.error.SolverError as exc:
            raise SolverError(f"payload SDP failed: {exc}") from None
        if prob.status not in ("optimal", "optimal_inaccurate") or x.value is None:
            raise SolverError(f"payload SDP ended with status '{prob.status}'")
        return kappa * np.asarray(x.value) / s


def _solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def _inertia_excitation(A: np.ndarray) -> float:
    """Smallest singular value of the column-equilibrated inertia block after removing the
    mass/CoM directions (Schur complement), relative to the largest of the whole matrix."""
    s = np.sqrt(np.maximum(np.diag(A), 1e-300))
    As = A / np.outer(s, s)
    S = As[4:, 4:] - As[4:, :4] @ np.linalg.pinv(As[:4, :4]) @ As[:4, 4:]
    return float(np.linalg.eigvalsh(S)[0] / np.linalg.eigvalsh(As)[-1])


def identify_payload(
    model,
    data: Trajectory | Iterable[Trajectory],
    frame: str,
    *,
    mode: str = "auto",
    com: Sequence[float] | None = None,
    consistent: bool = True,
    weights: str | None = "auto",
    n_boot: int = 200,
    block_seconds: float = 1.0,
    inertia_threshold: float = 1e-4,
    seed: int = 0,
    chunk: int = 2048,
) -> PayloadEstimate:
    """Estimate a payload at ``frame`` from logs taken with it attached (see module docstring).

    ``model``: the robot's identified model without the payload — an
    :class:`~sensorless.identification.IdentificationResult`, a fitted
    :class:`~sensorless.estimators.PhysicalModel` or a ``(structure, parameters)`` pair.
    ``weights``: "auto" (per-joint inverse residual variance) or None (ordinary LS).
    """
    if mode not in MODES:
        raise DataError(f"unknown payload mode '{mode}'; choose from {MODES}")
    structure, params = _unpack_model(model)
    robot = structure.robot
    if robot.floating_base:
        raise DataError("payload identification supports fixed-base arms only")
    robot.frame_id(frame)  # RobotModelError naming the known frames
    rows = structure.n_rows
    blocks = _Blocks(rows)
    ss_before = np.zeros(rows)
    n_total = 0
    for traj in iter_trajectories(data):
        if len(traj) < 2:
            raise DataError("a payload log needs at least 2 samples", traj.source)
        per_block = max(1, int(round(block_seconds / traj.dt)))
        for part in traj.chunks(max(per_block, 1) * max(1, chunk // per_block)):
            Q, V, A = structure.state(part)
            r = structure.target(part) - structure.evaluate(Q, V, A) @ params
            Y = payload_regressor(robot, Q, V, A, frame)
            for s in range(0, len(part), per_block):
                blocks.add(Y[s : s + per_block], r[s : s + per_block])
            ss_before += (r**2).sum(0)
            n_total += len(part)
    if n_total < 10:
        raise ExcitationError(f"only {n_total} samples; a payload needs a longer log")
    A_r, b_r, c_r, n = blocks.total()
    com_arr = np.zeros(3) if com is None else np.asarray(com, dtype=float)

    # two-step weights: OLS residual variance per joint
    w = np.ones(rows)
    if weights == "auto":
        phi0 = _solve_spd(A_r.sum(0) + 1e-12 * np.eye(10), b_r.sum(0))
        res = np.maximum(np.einsum("i,rij,j->r", phi0, A_r, phi0) - 2 * b_r @ phi0 + c_r, 0.0) / n
        w = 1.0 / np.maximum(res, 1e-12 * max(res.max(), 1e-300))
    elif weights is not None:
        raise DataError(f"weights must be 'auto' or None, got {weights!r}")
    Aw, bw = np.einsum("r,rij->ij", w, A_r), np.einsum("r,ri->i", w, b_r)
    if np.linalg.eigvalsh(Aw)[-1] <= 0:
        raise ExcitationError("the log does not move the payload frame (zero payload regressor)")
    excitation = _inertia_excitation(Aw)
    used = mode if mode != "auto" else ("full" if excitation > inertia_threshold else "com")
    solver = _Solver(used, consistent, com_arr)
    phi, cov_unit = solver(Aw, bw)
    res_ss = np.maximum(np.einsum("i,rij,j->r", phi, A_r, phi) - 2 * b_r @ phi + c_r, 0.0)
    # weighted residual variance factor (≈ 1 with the auto weights)
    dof = max(n * rows - (1 if used == "mass" else 4 if used == "com" else 10), 1)
    s2 = float(w @ res_ss) / dof
    cov = cov_unit * s2
    mass_std_a = float(np.sqrt(max(cov[0, 0], 0.0)))

    boot = None
    com_std = None
    if n_boot > 0 and len(blocks.n) >= 4:
        rng = np.random.default_rng(seed)
        nb = len(blocks.n)
        samples = []
        for _ in range(n_boot):
            idx = rng.integers(0, nb, nb)
            Ab, bb, _, _ = blocks.total(idx)
            samples.append(solver(np.einsum("r,rij->ij", w, Ab), np.einsum("r,ri->i", w, bb))[0])
        samples = np.array(samples)
        boot = float(samples[:, 0].std(ddof=1))
        ok = samples[:, 0] > 0
        if ok.sum() > 2 and used != "mass":
            com_std = (samples[ok, 1:4] / samples[ok, :1]).std(axis=0, ddof=1)
    eig = float(np.linalg.eigvalsh(pseudo_inertia(phi))[0])
    joints = list(structure.row_names)
    return PayloadEstimate(
        frame=frame, mode=used, parameters=phi,
        mass_std=boot if boot is not None else mass_std_a, mass_std_analytic=mass_std_a, mass_std_bootstrap=boot,
        com_std=com_std, consistent=eig >= -1e-9 * max(1.0, abs(phi[0])), min_pseudo_inertia_eig=eig,
        residual_rms_before=np.sqrt(ss_before / n), residual_rms_after=np.sqrt(res_ss / n), joints=joints,
        n_samples=int(n),
        settings={"mode": mode, "consistent": consistent, "weights": weights, "n_boot": n_boot,
                  "block_seconds": block_seconds, "inertia_threshold": inertia_threshold, "seed": seed,
                  "com": None if com is None else list(map(float, com))},
        diagnostics={"inertia_excitation": excitation, "mode_used": used, "row_weights": dict(zip(joints, w.tolist())),
                     "n_blocks": len(blocks.n)},
    )

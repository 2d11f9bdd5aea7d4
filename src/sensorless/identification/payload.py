"""Payload (external-load) identification from the torque residual of an identified robot model.

A payload rigidly fixed to frame f is one more body. Its 10 parameters
φ = [m, m c, I_f] (Pinocchio order, inertia about the frame origin, in frame axes) enter
the joint torques linearly:

    r = τ − W(q, q̇, q̈) π̂  ≈  J_f(q)ᵀ Φ_f(q, q̇, q̈) φ + o  =  Y_p φ + o

with π̂ the identified robot parameters, Φ_f Pinocchio's body regressor of a body at the
frame (``pin.frameBodyRegressor``, after ``pin.rnea`` so gravity is included), J_f the
frame Jacobian in the LOCAL frame and o optional per-joint constant offsets (a torque bias
that changed since the model was identified, e.g. a recalibrated drive; ``offsets="auto"``
fits them where they are distinguishable from the payload's own torque). For
a robot driven through a transmission (joints q = Gθ + q₀, e.g. the dVRK PSM in motor
coordinates) the rows are mapped to the coordinates, Y_p = Gᵀ J_fᵀ Φ_f.

Paired no-load log (``no_load``): the same trajectory recorded without the payload, row by
row. The residual becomes r = [τ − W π̂]_load − [τ − W π̂]_no-load: whatever the model
misses along the trajectory (unmodelled friction, cable effects, a wrong parameter) repeats
in both logs and cancels; the model only corrects the small difference between the two
executions. With offsets on, a session drift between the two recordings cancels too.

Estimators (``mode``):

* ``"full"``: all 10 parameters, weighted least squares; if the solution is not physically
  consistent, the convex problem min ‖L(Y_p φ − r)‖² s.t. pseudo-inertia J(φ) ⪰ 0 is solved
  with cvxpy + Clarabel (a small SDP).
* ``"com"``: mass and centre of mass, the payload taken as a point mass
  (I_f = m S(c), iterated on c) — for data that does not excite its rotational inertia.
* ``"mass"``: mass only, the CoM given (default: the frame origin).
* ``"auto"``: "full" if the inertia columns are excited (see ``inertia_threshold``), else "com".

The offsets are eliminated exactly (Schur complement of their diagonal block), so every
estimator works on the reduced normal equations in φ. Rows are weighted by the inverse
residual variance per joint (two-step, as in WLS).

Uncertainty (logs are time series: residuals are correlated in time and across joints):

* ``mass_std_analytic``: σ² (Yᵀ W Y)⁻¹ — white-noise assumption, optimistic; for reference.
* ``mass_std_hac``: block sandwich (batch-means HAC) covariance H⁻¹ (Σ_b s_b s_bᵀ) H⁻¹ ·
  B/(B − k), with s_b the score of block b (``block_seconds`` long, all joints together)
  and H the normal matrix of the estimator's parameters (mass; mass and first moment; all
  10) after the offsets are profiled out. Valid for noise correlated over less than a block.
* ``mass_std_bootstrap``: block bootstrap (blocks resampled with replacement, re-solved).

``mass_std`` is the larger of the HAC and bootstrap values. Both see noise, not a bias of
the model: that is what the paired no-load log is for.

Per-joint consistency: with the payload's shape u = φ/m fixed at the estimate, each joint's
equation alone implies a mass m_j (with its own offset when fitted), with its HAC standard
error σ_j, and the other informative joints together imply m_¬j (σ_¬j). A joint is flagged
when it contradicts the others both statistically (|m_j − m_¬j| > ``flag_sigma`` ·
√(σ_j² + σ_¬j²)) and materially (|m_j − m_¬j| > ``flag_rel`` · |m|); joints that hardly see
the payload (σ_j > |m|) are reported as uninformative, never flagged. A wrong joint also
distorts the fitted shape u, so flagged joints are set aside one at a time (largest |z|
first), the shape refitted without them and the others re-checked;
``diagnostics["mass_without_flagged"]`` is the mass without the flagged joints.
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

__all__ = ["JointConsistency", "PayloadEstimate", "identify_payload", "payload_regressor", "point_mass_parameters"]

MODES = ("auto", "full", "com", "mass")
MAX_COM = 10.0
"""[m] A point-mass CoM farther than this from the frame is taken as "no payload" (mode com):
it only happens when the fitted mass is ≈ 0 and c = (m c)/m is noise over noise."""


def payload_regressor(robot: Robot, Q: np.ndarray, V: np.ndarray, A: np.ndarray, frame: str) -> np.ndarray:
    """Y_p (N, n_actuated, 10): actuated joint torques per unit payload parameter at ``frame``.

    For a coordinate robot (transmission q = Gθ + q₀) Q, V, A are coordinate arrays θ, θ̇, θ̈
    and the rows are the coordinates' generalised forces, Gᵀ J_fᵀ Φ_f."""
    fid = robot.frame_id(frame)
    model, data = robot.model, robot.data
    act = robot.actuated_v_indices
    G = robot.transmission_matrix
    if G is not None:
        Q, V, A = robot.tree_state(Q, V, A)
    out = np.empty((Q.shape[0], len(act), 10))
    for i in range(Q.shape[0]):
        pin.rnea(model, data, Q[i], V[i], A[i])
        Phi = pin.frameBodyRegressor(model, data, fid).copy()
        J = pin.computeFrameJacobian(model, data, Q[i], fid, pin.LOCAL)
        Y = J.T @ Phi
        out[i] = (Y if G is None else G.T @ Y)[act]
    return out


def _skew_sq(c: np.ndarray) -> np.ndarray:
    return (c @ c) * np.eye(3) - np.outer(c, c)


def point_mass_parameters(mass: float, com: np.ndarray) -> np.ndarray:
    """φ of a point mass at ``com`` (frame coordinates): [m, m c, m S(c)], S(c) = |c|² 1 − c cᵀ."""
    com = np.asarray(com, dtype=float)
    I = mass * _skew_sq(com)
    return np.concatenate([[mass], mass * com, [I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]]])


@dataclass
class JointConsistency:
    """The mass one joint alone implies vs the mass the other joints imply (payload shape fixed)."""

    joint: str
    mass: float  # m_j from this joint's equation alone
    std: float  # its HAC standard error σ_j
    others_mass: float  # m from every other informative joint
    others_std: float
    z: float  # (m_j − m_others) / √(σ_j² + σ_others²)
    share: float  # fraction of the payload information this joint carries
    informative: bool  # σ_j < |m|
    flagged: bool
    offset: float | None  # offset of this joint in its own fit, when fitted

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("joint", "mass", "std", "others_mass", "others_std", "z", "share",
                                              "informative", "flagged", "offset")}


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
    mass_std_hac: float | None = None
    covariance: np.ndarray | None = None  # HAC covariance of φ (10 × 10)
    offsets: np.ndarray | None = None  # per-joint offsets (when fitted)
    per_joint: list[JointConsistency] = field(default_factory=list)
    gravity: float = 9.81

    @property
    def mass(self) -> float:
        return float(self.parameters[0])

    @property
    def weight(self) -> float:
        """m·g [N] (|g| of the robot model)."""
        return self.mass * self.gravity

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

    @property
    def flagged_joints(self) -> list[str]:
        return [c.joint for c in self.per_joint if c.flagged]

    def __str__(self) -> str:
        c = ", ".join(f"{x * 1e3:.1f}" for x in self.com)
        out = f"payload at '{self.frame}': m = {self.mass:.4f} ± {self.mass_std:.4f} kg, CoM = ({c}) mm [{self.mode}]"
        if self.flagged_joints:
            out += f"; joint(s) {self.flagged_joints} contradict the others"
        return out

    def to_dict(self) -> dict:
        return {
            "frame": self.frame, "mode": self.mode, "mass": self.mass, "mass_std": self.mass_std,
            "weight_N": self.weight, "weight_std_N": self.mass_std * self.gravity,
            "mass_std_analytic": self.mass_std_analytic, "mass_std_hac": self.mass_std_hac,
            "mass_std_bootstrap": self.mass_std_bootstrap,
            "com": self.com.tolist(), "com_std": None if self.com_std is None else self.com_std.tolist(),
            "inertia_com": self.inertia_com.tolist(), "parameters": self.parameters.tolist(),
            "covariance": None if self.covariance is None else self.covariance.tolist(),
            "offsets": None if self.offsets is None else dict(zip(self.joints, self.offsets.tolist())),
            "per_joint": [c.to_dict() for c in self.per_joint], "flagged_joints": self.flagged_joints,
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
    """Per-block, per-row normal equations of [Y_p, 1] z ≈ r (11 columns: φ and the row's offset)."""

    def __init__(self, rows: int) -> None:
        self.A: list[np.ndarray] = []  # (rows, 11, 11) per block
        self.b: list[np.ndarray] = []  # (rows, 11)
        self.c: list[np.ndarray] = []  # (rows,)
        self.n: list[int] = []
        self.rows = rows

    def add(self, Y: np.ndarray, r: np.ndarray) -> None:
        X = np.concatenate([Y, np.ones(Y.shape[:2] + (1,))], axis=2).transpose(1, 0, 2)  # (rows, n, 11)
        self.A.append(np.einsum("rni,rnj->rij", X, X))
        self.b.append(np.einsum("rni,nr->ri", X, r))
        self.c.append(np.einsum("nr,nr->r", r, r))
        self.n.append(Y.shape[0])

    def total(self, idx=None):
        sel = range(len(self.A)) if idx is None else idx
        return (sum(self.A[i] for i in sel), sum(self.b[i] for i in sel), sum(self.c[i] for i in sel),
                sum(self.n[i] for i in sel))


class _System:
    """Weighted normal equations in z = [φ (10), o (rows)] and their reduction to φ."""

    def __init__(self, A: np.ndarray, b: np.ndarray, w: np.ndarray, offsets: np.ndarray) -> None:
        self.mask = np.asarray(offsets, bool)  # rows with a free offset
        self.offsets = bool(self.mask.any())
        mw = w * self.mask
        self.App = np.einsum("r,rij->ij", w, A[:, :10, :10])
        self.bp = np.einsum("r,ri->i", w, b[:, :10])
        self.Apo = (mw[:, None] * A[:, :10, 10]).T  # (10, R), zero columns for rows without offset
        self.Aoo = np.where(self.mask & (w > 0), w * A[:, 10, 10], 1.0)  # diagonal (R,); a row set aside: 1
        self.bo = mw * b[:, 10]
        K = self.Apo / self.Aoo
        self.Ar = self.App - K @ self.Apo.T
        self.br = self.bp - K @ self.bo

    def offsets_for(self, phi: np.ndarray) -> np.ndarray:
        return np.where(self.mask, (self.bo - self.Apo.T @ phi) / self.Aoo, 0.0)

    def profile_score(self, Ab: np.ndarray, bb: np.ndarray, w: np.ndarray, phi: np.ndarray, o: np.ndarray) -> np.ndarray:
        """Score of one block for φ with the offsets profiled out: g_φ − A_φo A_oo⁻¹ g_o."""
        z_res_p = bb[:, :10] - np.einsum("rij,j->ri", Ab[:, :10, :10], phi) - Ab[:, :10, 10] * o[:, None]
        g_p = np.einsum("r,ri->i", w, z_res_p)
        g_o = w * self.mask * (bb[:, 10] - Ab[:, 10, :10] @ phi - Ab[:, 10, 10] * o)
        return g_p - (self.Apo / self.Aoo) @ g_o


class _Solver:
    """The estimator of one mode on reduced weighted normal equations (A 10×10, b 10)."""

    def __init__(self, mode: str, consistent: bool, com: np.ndarray | None) -> None:
        self.mode, self.consistent, self.com = mode, consistent, com
        self._basis = pseudo_inertia_basis()

    def __call__(self, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(φ, inverse of the used normal matrix in φ coordinates, Jacobian Gφ of φ = Gφ x)."""
        if self.mode == "mass":
            g = point_mass_parameters(1.0, self.com)
            a, bb = float(g @ A @ g), float(g @ b)
            if a <= 0:
                raise ExcitationError("the payload mass is not excited by this log (zero regressor)")
            m = max(bb / a, 0.0)
            return m * g, np.outer(g, g) / a, g[:, None]
        if self.mode == "com":
            c = np.zeros(3)
            for _ in range(10):
                G = np.zeros((10, 4))  # φ = G [m, h]: inertia of a point mass at the current c
                G[0, 0] = 1.0
                G[1:4, 1:4] = np.eye(3)
                G[4:, 0] = point_mass_parameters(1.0, c)[4:]
                Ar, br = G.T @ A @ G, G.T @ b
                x = _solve_spd(Ar, br)
                c_new = x[1:4] / x[0] if x[0] > 0 else np.zeros(3)
                if not (x[0] > 0 and np.all(np.isfinite(c_new)) and np.linalg.norm(c_new) < MAX_COM):
                    x, c_new = np.zeros(4), np.zeros(3)  # no (physical) payload: m ≤ 0 or CoM out of reach
                if np.allclose(c_new, c, atol=1e-9):
                    break
                c = c_new
            phi = point_mass_parameters(x[0], c) if x[0] > 0 else np.zeros(10)
            return phi, G @ np.linalg.pinv(Ar) @ G.T, G
        phi = _solve_spd(A, b)
        cov = np.linalg.pinv(A)
        if self.consistent and np.linalg.eigvalsh(pseudo_inertia(phi))[0] < 0:
            phi = self._sdp(A, b)
        return phi, cov, np.eye(10)

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


def _solve_without(solver, A_r, b_r, w, off_mask) -> "np.ndarray | None":
    """φ from the joints with weight w > 0, or None when they cannot determine it (a
    singular or non-finite reduced system, e.g. every joint set aside)."""
    if not np.any(w > 0):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        sys_x = _System(A_r, b_r, w, off_mask)
    if not (np.all(np.isfinite(sys_x.Ar)) and np.all(np.isfinite(sys_x.br))):
        return None
    try:
        phi = solver(sys_x.Ar, sys_x.br)[0]
    except (np.linalg.LinAlgError, ExcitationError, SolverError):
        return None
    return phi if np.all(np.isfinite(phi)) else None


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


def _sandwich(H: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """H⁻¹ (Σ s sᵀ) H⁻¹ · B/(B − k) for per-block scores (B, k)."""
    B, k = scores.shape
    Hi = np.linalg.pinv(H)
    return Hi @ (scores.T @ scores) @ Hi * (B / max(B - k, 1))


def _residual(structure: ModelStructure, params: np.ndarray, traj: Trajectory):
    Q, V, A = structure.state(traj)
    return (Q, V, A), structure.target(traj) - structure.evaluate(Q, V, A) @ params


def _paired(load: Trajectory, ref: Trajectory, structure: ModelStructure, max_dq: float) -> Trajectory:
    """The no-load log ``ref`` checked against ``load`` (row-aligned, same trajectory)."""
    if len(ref) != len(load):
        raise DataError(f"the no-load log has {len(ref)} samples but the payload log {load.source} has {len(load)}; "
                        "paired logs must be the same trajectory, row by row (trim them to the same rows)", ref.source)
    q_load, q_ref = structure.state(load)[0], structure.state(ref)[0]
    dq = np.abs(q_load - q_ref)
    if dq.size and dq.max() > max_dq:
        i, j = np.unravel_index(int(np.argmax(dq)), dq.shape)
        name = structure.robot.joint_names[j] if dq.shape[1] == len(structure.robot.joint_names) else f"#{j}"
        raise DataError(f"the no-load log differs from the payload log {load.source} by {dq.max():.4g} at sample {i}, "
                        f"joint '{name}' (> {max_dq:g}): not the same trajectory", ref.source)
    return ref


def identify_payload(
    model,
    data: Trajectory | Iterable[Trajectory],
    frame: str,
    *,
    no_load: Trajectory | Iterable[Trajectory] | None = None,
    offsets: bool | Sequence[str] = False,
    mode: str = "auto",
    com: Sequence[float] | None = None,
    consistent: bool = True,
    weights: str | None = "auto",
    n_boot: int = 200,
    block_seconds: float = 1.0,
    inertia_threshold: float = 1e-4,
    flag_sigma: float = 3.0,
    flag_rel: float = 0.1,
    max_pair_dq: float = 0.05,
    max_offset_inflation: float = 2.0,
    seed: int = 0,
    chunk: int = 2048,
) -> PayloadEstimate:
    """Estimate a payload at ``frame`` (a link's joint frame or any frame of the model) from
    logs taken with it attached (see module docstring).

    ``model``: the robot's identified model without the payload — an
    :class:`~sensorless.identification.IdentificationResult`, a fitted
    :class:`~sensorless.estimators.PhysicalModel` or a ``(structure, parameters)`` pair; any
    structure (URDF arm, a transmission such as the dVRK PSM). ``no_load``: one log per
    payload log, the same trajectory without the payload (row-aligned; positions within
    ``max_pair_dq``). ``offsets``: fit one constant torque offset per joint (True), on the
    listed joints only (names), none (False), or ``"auto"``: on every joint whose offset is
    distinguishable from the payload, i.e. fitting it alone multiplies the variance of the mass
    by less than ``max_offset_inflation`` (an offset on a joint that carries the payload's
    weight at a nearly constant angle, such as a vertical insertion axis, would absorb m·g).
    ``weights``: "auto" (per-joint inverse residual variance) or None (ordinary LS).
    """
    if mode not in MODES:
        raise DataError(f"unknown payload mode '{mode}'; choose from {MODES}")
    if weights not in ("auto", None):
        raise DataError(f"weights must be 'auto' or None, got {weights!r}")
    if block_seconds <= 0:
        raise DataError(f"block_seconds must be > 0, got {block_seconds}")
    structure, params = _unpack_model(model)
    robot = structure.robot
    if robot.floating_base:
        raise DataError("payload identification supports fixed-base arms only")
    robot.frame_id(frame)  # RobotModelError naming the known frames
    if params.shape != (structure.n_params,):
        raise DataError(f"the model has {params.size} parameters, its structure expects {structure.n_params}")
    logs = list(iter_trajectories(data))
    refs = None
    if no_load is not None:
        refs = list(iter_trajectories(no_load))
        if len(refs) != len(logs):
            raise DataError(f"{len(logs)} payload log(s) but {len(refs)} no-load log(s); pair them one to one")
    rows = structure.n_rows
    joints = list(structure.row_names)
    auto_offsets = isinstance(offsets, str) and offsets == "auto"
    if auto_offsets:
        off_mask = np.ones(rows, bool)  # refined below
    elif isinstance(offsets, str):
        raise DataError(f"offsets must be True, False, 'auto' or a list of joints, got {offsets!r}")
    elif isinstance(offsets, (bool, np.bool_)):
        off_mask = np.full(rows, bool(offsets))
    else:
        names = [str(j) for j in offsets]
        unknown = [j for j in names if j not in joints]
        if unknown:
            raise DataError(f"offsets for unknown joint(s) {unknown}; the model's joints are {joints}")
        off_mask = np.array([j in names for j in joints])
    blocks = _Blocks(rows)
    ss_before = np.zeros(rows)
    n_total = 0
    for k, traj in enumerate(logs):
        if len(traj) < 2:
            raise DataError("a payload log needs at least 2 samples", traj.source)
        ref = None if refs is None else _paired(traj, refs[k], structure, max_pair_dq)
        per_block = max(1, int(round(block_seconds / traj.dt)))
        size = per_block * max(1, chunk // per_block)
        for s0 in range(0, len(traj), size):
            part = traj.take(slice(s0, s0 + size))
            (Q, V, A), r = _residual(structure, params, part)
            if ref is not None:
                r = r - _residual(structure, params, ref.take(slice(s0, s0 + size)))[1]
            if not np.all(np.isfinite(r)):
                bad = int(np.argwhere(~np.isfinite(r))[0, 0])
                raise DataError(f"torque residual is not finite at sample {s0 + bad}", traj.source)
            Y = payload_regressor(robot, Q, V, A, frame)
            for s in range(0, len(part), per_block):
                blocks.add(Y[s : s + per_block], r[s : s + per_block])
            ss_before += (r**2).sum(0)
            n_total += len(part)
    if n_total < 10:
        raise ExcitationError(f"only {n_total} samples; a payload needs a longer log")
    A_r, b_r, c_r, n = blocks.total()
    com_arr = np.zeros(3) if com is None else np.asarray(com, dtype=float).reshape(3)

    def row_ss(phi: np.ndarray, o: np.ndarray) -> np.ndarray:
        z = np.concatenate([np.broadcast_to(phi, (rows, 10)), o[:, None]], axis=1)  # (rows, 11)
        return np.maximum(np.einsum("ri,rij,rj->r", z, A_r, z) - 2 * np.einsum("ri,ri->r", b_r, z) + c_r, 0.0)

    def row_weights(mask: np.ndarray) -> np.ndarray:
        """Two-step weights: inverse OLS residual variance per joint."""
        if weights != "auto":
            return np.ones(rows)
        sys0 = _System(A_r, b_r, np.ones(rows), mask)
        phi0 = _solve_spd(sys0.Ar + 1e-12 * np.trace(sys0.Ar) * np.eye(10) / 10, sys0.br)
        res = row_ss(phi0, sys0.offsets_for(phi0)) / n
        return 1.0 / np.maximum(res, 1e-12 * max(res.max(), 1e-300))

    w = row_weights(off_mask)
    inflation = _offset_inflation(A_r, b_r, w)
    if auto_offsets:
        off_mask = np.array([v < max_offset_inflation for v in inflation])
        w = row_weights(off_mask)
    system = _System(A_r, b_r, w, off_mask)
    if np.linalg.eigvalsh(system.Ar)[-1] <= 0:
        raise ExcitationError("the log does not move the payload frame (zero payload regressor)")
    excitation = _inertia_excitation(system.Ar)
    used = mode if mode != "auto" else ("full" if excitation > inertia_threshold else "com")
    solver = _Solver(used, consistent, com_arr)
    phi, cov_unit, Gphi = solver(system.Ar, system.br)
    o = system.offsets_for(phi)
    res_ss = row_ss(phi, o)
    k_par = Gphi.shape[1] + int(off_mask.sum())
    dof = max(n * rows - k_par, 1)
    s2 = float(w @ res_ss) / dof
    mass_std_a = float(np.sqrt(max(cov_unit[0, 0] * s2, 0.0)))

    # HAC (block sandwich) covariance of φ = Gφ x, offsets profiled out
    nb = len(blocks.n)
    scores = np.array([system.profile_score(blocks.A[i], blocks.b[i], w, phi, o) for i in range(nb)]) @ Gphi
    cov_x = _sandwich(Gphi.T @ system.Ar @ Gphi, scores)
    cov = Gphi @ cov_x @ Gphi.T
    mass_std_hac = float(np.sqrt(max(cov[0, 0], 0.0)))
    com_std = None
    if used != "mass" and phi[0] > 0:
        Jc = np.zeros((3, 10))  # c = h / m
        Jc[:, 0] = -phi[1:4] / phi[0] ** 2
        Jc[:, 1:4] = np.eye(3) / phi[0]
        com_std = np.sqrt(np.maximum(np.diag(Jc @ cov @ Jc.T), 0.0))

    boot = None
    if n_boot > 0 and nb >= 4:
        rng = np.random.default_rng(seed)
        samples = []
        for _ in range(n_boot):
            Ab, bb, _, _ = blocks.total(rng.integers(0, nb, nb))
            sb = _System(Ab, bb, w, off_mask)
            samples.append(solver(sb.Ar, sb.br)[0])
        samples = np.array(samples)
        boot = float(samples[:, 0].std(ddof=1))
        ok = samples[:, 0] > 0
        if ok.sum() > 2 and used != "mass":
            com_boot = (samples[ok, 1:4] / samples[ok, :1]).std(axis=0, ddof=1)
            com_std = com_boot if com_std is None else np.maximum(com_std, com_boot)
    mass_std = max(mass_std_hac, boot) if boot is not None else mass_std_hac
    # per-joint check; a contradicting joint also distorts the fitted shape, so flagged joints are
    # set aside one at a time (largest |z| first) and the others re-checked without them
    excluded = np.zeros(rows, bool)
    final: dict[int, JointConsistency] = {}
    phi_ok = phi
    checks: list = []
    for _ in range(rows):
        if excluded.any():
            phi_x = _solve_without(solver, A_r, b_r, w * ~excluded, off_mask)
            if phi_x is None:  # the joints left cannot determine the payload: stop setting joints aside
                final.update({r: c for r, c in enumerate(checks) if r not in final})
                break
            phi_ok = phi_x
        checks = _per_joint(blocks, A_r, b_r, w, phi_ok, cov, off_mask, joints, flag_sigma, flag_rel, excluded)
        bad = [r for r, c in enumerate(checks) if c.flagged and not excluded[r]]
        if not bad:
            final.update({r: c for r, c in enumerate(checks) if not excluded[r]})
            break
        worst = max(bad, key=lambda r: abs(checks[r].z))
        final[worst] = checks[worst]
        excluded[worst] = True
    per_joint = [final[r] for r in range(rows)]
    eig = float(np.linalg.eigvalsh(pseudo_inertia(phi))[0])
    gravity = float(np.linalg.norm(robot.model.gravity.linear))
    return PayloadEstimate(
        frame=frame, mode=used, parameters=phi,
        mass_std=mass_std, mass_std_analytic=mass_std_a, mass_std_bootstrap=boot, mass_std_hac=mass_std_hac,
        com_std=com_std, consistent=eig >= -1e-9 * max(1.0, abs(phi[0])), min_pseudo_inertia_eig=eig,
        residual_rms_before=np.sqrt(ss_before / n), residual_rms_after=np.sqrt(res_ss / n), joints=joints,
        n_samples=int(n), covariance=cov, offsets=o if off_mask.any() else None, per_joint=per_joint, gravity=gravity,
        settings={"mode": mode, "consistent": consistent, "weights": weights, "n_boot": n_boot,
                  "block_seconds": block_seconds, "inertia_threshold": inertia_threshold, "seed": seed,
                  "com": None if com is None else list(map(float, com)),
                  "offsets": [j for j, f in zip(joints, off_mask) if f],
                  "paired_no_load": refs is not None, "flag_sigma": flag_sigma, "flag_rel": flag_rel},
        diagnostics={"inertia_excitation": excitation, "mode_used": used, "row_weights": dict(zip(joints, w.tolist())),
                     "offset_variance_inflation": dict(zip(joints, map(float, inflation))),
                     "n_blocks": nb, "residual_variance_factor": s2,
                     "mass_without_flagged": float(phi_ok[0]) if excluded.any() else None,
                     "mass_unconstrained": _unconstrained_mass(system, phi, com_arr)},
    )


def _unconstrained_mass(system: _System, phi: np.ndarray, com: np.ndarray) -> float:
    """Least-squares mass with the CoM fixed (at the estimate, or ``com`` when m = 0) and no
    positivity: shows how negative the data would have it when the estimate is clamped at 0."""
    c = phi[1:4] / phi[0] if phi[0] > 0 else com
    g = point_mass_parameters(1.0, c)
    a = float(g @ system.Ar @ g)
    return float(g @ system.br) / a if a > 0 else float("nan")


def _offset_inflation(A_r: np.ndarray, b_r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per joint: factor by which an offset on that joint alone multiplies the (white-noise)
    variance of the mass, from the mass / first-moment block of the reduced normal equations."""
    rows = A_r.shape[0]

    def var_m(mask) -> float:
        return float(np.linalg.pinv(_System(A_r, b_r, w, mask).Ar[:4, :4])[0, 0])

    base = var_m(np.zeros(rows, bool))
    if base <= 0:
        return np.ones(rows)
    return np.array([var_m(np.eye(rows, dtype=bool)[j]) / base for j in range(rows)])


def _scalar_fit(blocks: _Blocks, A_r, b_r, w, u, offsets, rows, hac: bool = True) -> tuple[float, float, dict]:
    """Mass m of the payload shape u from the equations of ``rows`` only (their offsets free
    where ``offsets``), with its HAC standard error: x = [m, o_r …], row r has features T_rᵀ = [Y_r u, e_r]."""
    rows = [r for r in rows]
    off_rows = [r for r in rows if offsets[r]]
    k = 1 + len(off_rows)
    T = {}
    for r in rows:
        Tr = np.zeros((11, k))
        Tr[:10, 0] = u
        if offsets[r]:
            Tr[10, 1 + off_rows.index(r)] = 1.0
        T[r] = Tr
    H = sum(w[r] * T[r].T @ A_r[r] @ T[r] for r in rows)
    g = sum(w[r] * T[r].T @ b_r[r] for r in rows)
    if not rows or H[0, 0] <= 1e-14 * max(np.abs(H).max(), 1e-300):
        return float("nan"), float("inf"), {}
    x = _solve_spd(H, g)
    if not hac:
        return float(x[0]), float("nan"), {}
    scores = np.array([sum(w[r] * T[r].T @ (blocks.b[i][r] - blocks.A[i][r] @ (T[r] @ x)) for r in rows)
                       for i in range(len(blocks.n))])
    std = float(np.sqrt(max(_sandwich(H, scores)[0, 0], 0.0)))
    return float(x[0]), std, {r: float(x[1 + off_rows.index(r)]) for r in off_rows}


def _per_joint(blocks: _Blocks, A_r, b_r, w, phi, cov, offsets, joints, flag_sigma, flag_rel, excluded) -> list[JointConsistency]:
    """Per joint: the mass its equation alone implies vs the mass all other informative joints
    (``excluded`` left out) imply, payload shape u = φ/m fixed, offsets free where fitted
    (module docstring). Standard errors: HAC of the scalar fit plus the propagated uncertainty
    of the shape, Σ_k ((m(φ + √λ_k v_k) − m(φ − √λ_k v_k))/2)² over the eigenpairs of the
    covariance of φ (a joint whose payload torque hinges on the CoM, such as a wrist joint,
    gets the CoM's uncertainty). ``share``: the joint's part of the weighted information
    uᵀ(Σ_r w_r Y_rᵀY_r)u."""
    m = float(phi[0])
    R = len(joints)
    if m <= 0:
        return [JointConsistency(j, float("nan"), float("nan"), float("nan"), float("nan"), float("nan"), 0.0,
                                 False, False, None) for j in joints]
    u = phi / m
    info = w * np.einsum("i,rij,j->r", u, A_r[:, :10, :10], u)
    share = info / max(info.sum(), 1e-300)
    lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))
    steps = [np.sqrt(l) * v for l, v in zip(lam, vec.T) if l > 1e-12 * max(lam.max(), 1e-300)]

    def fit(rows):
        mj, sj, off = _scalar_fit(blocks, A_r, b_r, w, u, offsets, rows)
        if not np.isfinite(sj):
            return mj, sj, off
        shape2 = 0.0
        for d in steps:
            up, dn = phi + d, phi - d
            if up[0] <= 0 or dn[0] <= 0:
                continue
            mp = _scalar_fit(blocks, A_r, b_r, w, up / up[0], offsets, rows, hac=False)[0]
            mm = _scalar_fit(blocks, A_r, b_r, w, dn / dn[0], offsets, rows, hac=False)[0]
            shape2 += (0.5 * (mp - mm)) ** 2
        return mj, float(np.hypot(sj, np.sqrt(shape2))), off

    fits = [fit([r]) for r in range(R)]
    informative = [bool(np.isfinite(f[1]) and f[1] < abs(m)) for f in fits]
    out = []
    for r, name in enumerate(joints):
        mj, sj, off = fits[r]
        others = [k for k in range(R) if k != r and informative[k] and not excluded[k]]
        mo, so, _ = fit(others) if others else (float("nan"), float("inf"), {})
        d = mj - mo
        z = d / max(float(np.hypot(sj, so)), 1e-300) if np.isfinite(d) and np.isfinite(so) else 0.0
        flagged = informative[r] and np.isfinite(so) and abs(z) > flag_sigma and abs(d) > flag_rel * abs(m)
        out.append(JointConsistency(name, mj, sj, mo, so, float(z), float(share[r]), informative[r], bool(flagged),
                                    off.get(r)))
    return out

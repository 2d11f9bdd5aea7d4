"""Acceleration-free identification: the filtered momentum regressor.

Write the model's generalised forces with the momentum p = M(q) v (identified armature
included), linear in the parameters θ = [π, φ]:

    Sᵀτ = ṗ + b,        p = Y_p(q, v) θ,        b = Y_b(q, v) θ,

* body columns: Y_p = Y(q, 0, v) on the gravity-free model (so Y_p π = M v), and
  Y_b = Y(q, v, 0) − D_v Y_p(q, v), i.e. b = C v + g − Ṁ v = g − Cᵀ v (Ṁ = C + Cᵀ),
  where D_v is the derivative along the motion, q ⊕ (±ε v), by a central difference of
  Pinocchio's regressor (exact to O(ε²); no time derivative of the data);
* joint terms (:mod:`.joint_terms`): a term on v̇ (armature I_a) puts v_j in Y_p (p_j += I_a v_j);
  the others (viscous, Coulomb, offset, ...) put their columns [v, sgn v, 1, ...] in Y_b.

No accelerations appear: apply one stable low-pass L(s) = (λ/(s + λ))ⁿ (n = ``order``)
to both sides, from zero state at t₀,

    L[Sᵀτ] = s L[Y_p θ − p(t₀)] + L[Y_b θ],

which holds exactly in continuous time and is linear in θ: the *filtered regressor*
W_f = s L[Y_p − Y_p(t₀)] + L[Y_b], target y_f = L[Sᵀτ]
(:class:`~sensorless.data.integral_filter.LowpassChain`). The samples are integrated
exactly for piecewise-linear signals (first-order hold) — and the torque either the same
way (``tau_hold="linear"``: a log of instantaneous torque samples, the trapezoid rule) or as
piecewise constant (``"mean"``: a log of each period's mean torque, then ∫τ dt is exact).
On a fixed base the only approximation is the interpolation between log samples; with a
1 kHz controller logged at 100 Hz the instantaneous torque aliases (trot, jump), which
``"mean"`` logs remove. Order n ≥ 2 makes s L a band-pass, so the velocity noise, which
enters through s L[M v] with gain ≈ λ at high frequency for n = 1, is attenuated too.

Contact null-space projection (legged robots, no force sensing): P(q) = I − Jc⁺Jc removes
Jcᵀ f only when it multiplies the equation *before* filtering, and P varies in time:

    P Sᵀτ = P ṗ + P b = d/dt(P p) − Ṗ p + P b,      Ṗ = D_v P(q)  (same central difference),

so W_f = s L[P Y_p − (P Y_p)(t₀)] + L[P Y_b − Ṗ Y_p], y_f = L[P Sᵀτ]. P also jumps when
the contact pattern changes; the filters restart at every change (segments of constant
pattern), which drops the interval in which the switch happened. Dropping the Ṗ p term
(``pdot=False``) is the approximation "P constant over the filter's memory"; its error is
measured by :func:`projection_rate_error`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..data.filtering import uniform_dt
from ..data.integral_filter import LowpassChain
from ..data.gains import no_effort_message
from ..data.trajectory import Trajectory
from ..errors import DataError, RobotModelError, setting
from .joint_terms import joint_term
from .terms import ModelStructure, in_robot_order

__all__ = ["FilteredRows", "filtered_rows", "filtered_target", "momentum_regressors", "projection_rate_error"]


def _gravity_free(model: pin.Model) -> tuple[pin.Model, pin.Data]:
    m = model.copy()
    m.gravity = pin.Motion.Zero()
    return m, m.createData()


def momentum_regressors(structure: ModelStructure, Q: np.ndarray, V: np.ndarray, eps: float = 1e-5
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(Y_p, Y_b), each (N, nv, n_params), on all nv rows (see the module docstring)."""
    r = structure.robot
    model, data = r.model, r.data
    m0, d0 = _gravity_free(model)
    f = pin.computeJointTorqueRegressor
    N, nv = Q.shape[0], r.nv
    nb = structure.n_body_params
    Yp = np.zeros((N, nv, structure.n_params))
    Yb = np.zeros_like(Yp)
    z = np.zeros(nv)
    for i in range(N):
        q, v = Q[i], V[i]
        Yp[i, :, :nb] = f(m0, d0, q, z, v)
        qp, qm = pin.integrate(model, q, eps * v), pin.integrate(model, q, -eps * v)
        dYp = (f(m0, d0, qp, z, v) - f(m0, d0, qm, z, v)) / (2 * eps)
        Yb[i, :, :nb] = f(model, data, q, v, z) - dYp
    act = r.actuated_v_indices
    nt = len(structure.joint_terms)
    F = structure.joint_features(V, np.zeros_like(V))  # (N, n_act, nt); armature column 0
    for k, row in enumerate(act):
        c = nb + k * nt
        for t_i, term in enumerate(structure.joint_terms):
            if joint_term(term).acceleration:  # a column v̇: its momentum column is v
                Yp[:, row, c + t_i] = V[:, row]
            else:
                Yb[:, row, c + t_i] = F[:, k, t_i]
    return Yp, Yb


def _segments(flags: np.ndarray | None, N: int) -> list[tuple[int, int]]:
    """[start, stop) runs of a constant contact pattern (one segment without flags)."""
    if flags is None or N == 0:
        return [(0, N)]
    change = np.flatnonzero(np.any(flags[1:] != flags[:-1], axis=1)) + 1
    bounds = np.concatenate([[0], change, [N]])
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


@dataclass
class FilteredRows:
    """Filtered regressor W (N, rows, n_params) and target y (N, rows) of one log."""

    W: np.ndarray
    y: np.ndarray
    segment_start: np.ndarray  # (N,) bool: first sample of a constant-contact segment


def _state(structure: ModelStructure, traj: Trajectory):
    r = structure.robot
    if traj.v is None:
        raise DataError("acceleration-free identification needs joint velocities 'v'", traj.source)
    tr = in_robot_order(r, traj)
    if r.floating_base and (tr.base_q is None or tr.base_v is None):
        raise DataError("a floating-base robot needs base_q and base_v in the log", traj.source)
    return r.full_configuration(tr.q, tr.base_q), r.full_velocity(tr.v, tr.base_v)


def _generalised(structure: ModelStructure, traj: Trajectory, tau: np.ndarray | None) -> np.ndarray:
    """Sᵀτ (N, nv) from actuated torques (N, n_actuated), default the log's."""
    r = structure.robot
    if tau is None:
        if traj.tau is None:
            raise DataError(no_effort_message(traj), traj.source)
        tr = in_robot_order(r, traj)
        tau = tr.tau[:, [r.joint_names.index(j) for j in r.actuated_joints]]
    out = np.zeros((len(traj), r.nv))
    out[:, r.actuated_v_indices] = tau
    return out


def _projectors(structure, Q, V, flags, eps):
    P = structure.projector(Q, flags)
    Qp = np.array([pin.integrate(structure.robot.model, q, eps * v) for q, v in zip(Q, V)])
    Qm = np.array([pin.integrate(structure.robot.model, q, -eps * v) for q, v in zip(Q, V)])
    Pdot = (structure.projector(Qp, flags) - structure.projector(Qm, flags)) / (2 * eps)
    return P, Pdot


def _rows(structure) -> np.ndarray:
    return structure._row_idx


def _filter(cutoff: float, order: int, dt: float, tau_hold: str) -> LowpassChain:
    if tau_hold not in ("linear", "mean"):
        raise RobotModelError(f"tau_hold must be 'linear' (torque samples) or 'mean' (period means), got {tau_hold!r}")
    return LowpassChain(cutoff, order, dt)


def filtered_rows(structure: ModelStructure, traj: Trajectory, cutoff: float = 4.0, *, order: int = 1,
                  tau_hold: str = "linear", pdot: bool = True, eps: float = 1e-5) -> FilteredRows:
    """W_f and y_f of a whole log (see the module docstring); ``cutoff`` = λ/2π [Hz]."""
    lp = _filter(cutoff, order, _dt(traj), tau_hold)
    Q, V = _state(structure, traj)
    Yp, Yb = momentum_regressors(structure, Q, V, eps)
    y = _generalised(structure, traj, None)
    flags = None
    if structure.row_map.per_sample:  # contacts: P(q) before filtering
        if not structure.row_map.projected:
            raise RobotModelError(f"acceleration-free identification supports {setting('mode', 'projected')} contact "
                                  "structures")
        flags = structure.contacts(traj)
        P, Pd = _projectors(structure, Q, V, flags, eps)
        Yp_m = np.matmul(P, Yp)
        Yb = np.matmul(P, Yb) - (np.matmul(Pd, Yp) if pdot else 0.0)
        Yp = Yp_m
        y = np.einsum("nij,nj->ni", P, y)
    rows = _rows(structure)
    Yp, Yb, y = Yp[:, rows], Yb[:, rows], y[:, rows]
    W = np.empty_like(Yp)
    yf = np.empty_like(y)
    start = np.zeros(len(traj), bool)
    for s, e in _segments(flags, len(traj)):
        start[s] = True
        dp = Yp[s:e] - Yp[s]
        W[s:e] = lp.rate(lp.states(dp), dp) + lp.value(lp.states(Yb[s:e]))
        yf[s:e] = lp.value(lp.states(y[s:e], tau_hold))
    return FilteredRows(W, yf, start)


def filtered_target(structure: ModelStructure, traj: Trajectory, tau: np.ndarray | None = None,
                    cutoff: float = 4.0, *, order: int = 1, tau_hold: str = "linear") -> np.ndarray:
    """y_f = L[P Sᵀτ] (or L[Sᵀτ] on the kept rows) for actuated torques ``tau`` (N, n_actuated)
    of any model — e.g. a black-box MLP — or the log's; scored "the same way" as W_f θ."""
    lp = _filter(cutoff, order, _dt(traj), tau_hold)
    y = _generalised(structure, traj, tau)
    flags = None
    if structure.row_map.per_sample:  # contacts: P(q) before filtering
        Q, _ = _state(structure, traj)
        flags = structure.contacts(traj)
        y = np.einsum("nij,nj->ni", structure.projector(Q, flags), y)
    y = y[:, _rows(structure)]
    out = np.empty_like(y)
    for s, e in _segments(flags, len(traj)):
        out[s:e] = lp.value(lp.states(y[s:e], tau_hold))
    return out


def projection_rate_error(structure, traj: Trajectory, params: np.ndarray, cutoff: float = 4.0, **kw) -> dict:
    """Size of the Ṗ p term: RMS of W_f θ with and without it, and of their difference."""
    full = filtered_rows(structure, traj, cutoff, pdot=True, **kw)
    approx = filtered_rows(structure, traj, cutoff, pdot=False, **kw)
    a, b = full.W @ params, approx.W @ params
    rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
    return {"rms_with_pdot": rms(a), "rms_difference": rms(a - b), "relative": rms(a - b) / max(rms(a), 1e-300),
            "target_rms": rms(full.y)}


def _dt(traj: Trajectory) -> float:
    return uniform_dt(traj, "acceleration-free identification")

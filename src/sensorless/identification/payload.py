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

from typing import Callable, Iterable, Sequence

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, ExcitationError, setting
from ..parameters import pseudo_inertia
from ..regressor.normal_equations import iter_trajectories
from ..regressor.terms import ModelStructure
from .payload_fit import (
    PayloadBlocks,
    inertia_excitation,
    offset_inflation,
    joint_consistency,
    sandwich,
    solve_spd,
    solve_without,
    PayloadSolver,
    PayloadSystem,
    unconstrained_mass,
)
from .payload_determinacy import LEVER_TOL, verdicts
from .payload_model import JointConsistency, PayloadEstimate, payload_regressor, point_mass_parameters


__all__ = ["identify_payload"]

MODES = ("auto", "full", "com", "mass")


def _unpack_model(model) -> tuple[ModelStructure, np.ndarray]:
    if isinstance(model, tuple) and len(model) == 2:
        return model[0], np.asarray(model[1], dtype=float)
    for s_attr, p_attr in (("structure", "parameters"), ("structure_", "parameters_")):
        if hasattr(model, s_attr) and hasattr(model, p_attr):
            return getattr(model, s_attr), np.asarray(getattr(model, p_attr), dtype=float)
    raise DataError("model must be an IdentificationResult, a fitted PhysicalModel or a (structure, parameters) pair")


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
    progress: Callable[[int, int], None] | None = None,
) -> PayloadEstimate:
    """Estimate a payload at ``frame`` (a link's joint frame or any frame of the model) from
    logs taken with it attached (see module docstring).

    ``model``: the robot's identified model without the payload — an
    :class:`~sensorless.identification.IdentificationResult`, a fitted
    :class:`~sensorless.torque_models.PhysicalModel` or a ``(structure, parameters)`` pair; any
    structure (URDF arm, a transmission such as the dVRK PSM). ``no_load``: one log per
    payload log, the same trajectory without the payload (row-aligned; positions within
    ``max_pair_dq``). ``offsets``: fit one constant torque offset per joint (True), on the
    listed joints only (names), none (False), or ``"auto"``: on every joint whose offset is
    distinguishable from the payload, i.e. fitting it alone multiplies the variance of the mass
    by less than ``max_offset_inflation`` (an offset on a joint that carries the payload's
    weight at a nearly constant angle, such as a vertical insertion axis, would absorb m·g).
    ``weights``: "auto" (per-joint inverse residual variance) or None (ordinary LS).
    ``progress(done, n_boot)`` is called after each bootstrap resample (again from 1 if flagged joints
    are left out and the fit is repeated).
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
    blocks = PayloadBlocks(rows)
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

    def row_weights(mask: np.ndarray, keep: np.ndarray | None = None) -> np.ndarray:
        """Two-step weights: inverse OLS residual variance per joint (OLS on the ``keep`` rows)."""
        keep = np.ones(rows, bool) if keep is None else keep
        if weights != "auto":
            return keep.astype(float)
        sys0 = PayloadSystem(A_r, b_r, keep.astype(float), mask)
        phi0 = solve_spd(sys0.Ar + 1e-12 * np.trace(sys0.Ar) * np.eye(10) / 10, sys0.br)
        res = row_ss(phi0, sys0.offsets_for(phi0)) / n
        return keep / np.maximum(res, 1e-12 * max(res.max(), 1e-300))

    w = row_weights(off_mask)
    inflation = offset_inflation(A_r, b_r, w)
    if auto_offsets:
        off_mask = np.array([v < max_offset_inflation for v in inflation])
        w = row_weights(off_mask)
    com_given = com is not None

    def fit(wts: np.ndarray) -> dict:
        """The estimate and its uncertainty from the joints with weight > 0."""
        system = PayloadSystem(A_r, b_r, wts, off_mask)
        if np.linalg.eigvalsh(system.Ar)[-1] <= 0:
            raise ExcitationError("the log does not move the payload frame (zero payload regressor)")
        excitation = inertia_excitation(system.Ar)
        used = mode if mode != "auto" else ("full" if excitation > inertia_threshold else "com")
        det = verdicts(system.Ar, mode=used, inertia_excitation=excitation, inertia_threshold=inertia_threshold,
                       mass_from_com=False)
        if det["mass"] == "undetermined":
            why = ("its origin does not move under the logged joints" if det["mass_lever_m"] < 1e-9 else
                   "the log cannot separate m from m·c (the frame's origin moves too little, or only rotates "
                   "about a fixed point)")
            if not com_given and used != "mass":
                raise ExcitationError(
                    f"the payload mass at frame '{frame}' is not determined by the log: {why} (only m·c, the first "
                    f"moment, is); give the payload's CoM in the frame ({setting('com', placeholder='X,Y,Z')}) to compute "
                    "m from m·c, or choose a frame whose origin moves")
            g = point_mass_parameters(1.0, com_arr)
            if np.sqrt(max(float(g @ system.Ar @ g), 0.0) / np.linalg.eigvalsh(system.Ar[:4, :4])[-1]) < LEVER_TOL:
                raise ExcitationError(f"the payload mass at frame '{frame}' is not determined: {why}, and at the CoM "
                                      f"given ({', '.join(f'{x:g}' for x in com_arr)} m) m·c carries no mass either")
            used = "mass"
            det = {**det, "mass": "from the given CoM", "inertia": "assumed (point mass)"}
        solver = PayloadSolver(used, consistent, com_arr)
        phi, cov_unit, Gphi = solver(system.Ar, system.br)
        o = system.offsets_for(phi)
        res_ss = row_ss(phi, o)
        k_par = Gphi.shape[1] + int(off_mask.sum())
        dof = max(n * int((wts > 0).sum()) - k_par, 1)
        s2 = float(wts @ res_ss) / dof
        # HAC (block sandwich) covariance of φ = Gφ x, offsets profiled out
        nb = len(blocks.n)
        scores = np.array([system.profile_score(blocks.A[i], blocks.b[i], wts, phi, o) for i in range(nb)]) @ Gphi
        cov = Gphi @ sandwich(Gphi.T @ system.Ar @ Gphi, scores) @ Gphi.T
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
            for k in range(n_boot):
                Ab, bb, _, _ = blocks.total(rng.integers(0, nb, nb))
                sb = PayloadSystem(Ab, bb, wts, off_mask)
                samples.append(solver(sb.Ar, sb.br)[0])
                if progress is not None:
                    progress(k + 1, n_boot)
            samples = np.array(samples)
            boot = float(samples[:, 0].std(ddof=1))
            ok = samples[:, 0] > 0
            if ok.sum() > 2 and used != "mass":
                com_boot = (samples[ok, 1:4] / samples[ok, :1]).std(axis=0, ddof=1)
                com_std = com_boot if com_std is None else np.maximum(com_std, com_boot)
        hac = float(np.sqrt(max(cov[0, 0], 0.0)))
        return dict(system=system, excitation=excitation, used=used, det=det, solver=solver, phi=phi, o=o,
                    res_ss=res_ss, s2=s2, cov=cov, com_std=com_std, boot=boot, nb=nb, mass_std_hac=hac,
                    mass_std_a=float(np.sqrt(max(cov_unit[0, 0] * s2, 0.0))),
                    mass_std=max(hac, boot) if boot is not None else hac)

    F = fit(w)
    # per-joint check; a contradicting joint also distorts the fitted shape, so flagged joints are
    # set aside one at a time (largest |z| first) and the others re-checked without them
    excluded = np.zeros(rows, bool)
    final: dict[int, JointConsistency] = {}
    phi_ok = F["phi"]
    checks: list = []
    for _ in range(rows):
        if excluded.any():
            phi_x = solve_without(F["solver"], A_r, b_r, w * ~excluded, off_mask)
            if phi_x is None:  # the joints left cannot determine the payload: no headline without the flagged ones
                names = [joints[r] for r in np.flatnonzero(excluded)]
                raise ExcitationError(
                    f"joint(s) {names} contradict the other joints' payload torque, and without them the log does "
                    f"not determine the payload at '{frame}'; check their torque channels and drive gains")
            phi_ok = phi_x
        checks = joint_consistency(blocks, A_r, b_r, w, phi_ok, F["cov"], off_mask, joints, flag_sigma, flag_rel, excluded)
        bad = [r for r, c in enumerate(checks) if c.flagged and not excluded[r]]
        if not bad:
            final.update({r: c for r, c in enumerate(checks) if not excluded[r]})
            break
        worst = max(bad, key=lambda r: abs(checks[r].z))
        final[worst] = checks[worst]
        excluded[worst] = True
    per_joint = [final[r] for r in range(rows)]
    mass_all = float(F["phi"][0])
    if excluded.any():  # the headline is the fit without the flagged joints
        w = row_weights(off_mask, ~excluded)
        F = fit(w)
    phi, cov, det = F["phi"], F["cov"], dict(F["det"])
    if phi[0] <= max(1e-9, 1e-3 * F["mass_std"]):
        det["mass"] = "at bound: not determined"
        det["first_moment"] = "at bound: not determined"
    eig = float(np.linalg.eigvalsh(pseudo_inertia(phi))[0])
    gravity = float(np.linalg.norm(robot.model.gravity.linear))
    dropped = [joints[r] for r in np.flatnonzero(excluded)]
    return PayloadEstimate(
        frame=frame, mode=F["used"], parameters=phi,
        mass_std=F["mass_std"], mass_std_analytic=F["mass_std_a"], mass_std_bootstrap=F["boot"],
        mass_std_hac=F["mass_std_hac"], com_std=F["com_std"], consistent=eig >= -1e-9 * max(1.0, abs(phi[0])),
        min_pseudo_inertia_eig=eig, residual_rms_before=np.sqrt(ss_before / n),
        residual_rms_after=np.sqrt(F["res_ss"] / n), joints=joints, n_samples=int(n), covariance=cov,
        offsets=F["o"] if off_mask.any() else None, per_joint=per_joint, gravity=gravity, determinacy=det,
        headline_excludes=dropped,
        settings={"mode": mode, "consistent": consistent, "weights": weights, "n_boot": n_boot,
                  "block_seconds": block_seconds, "inertia_threshold": inertia_threshold, "seed": seed,
                  "com": None if com is None else list(map(float, com)),
                  "offsets": [j for j, f in zip(joints, off_mask) if f],
                  "paired_no_load": refs is not None, "flag_sigma": flag_sigma, "flag_rel": flag_rel},
        diagnostics={"inertia_excitation": F["excitation"], "mode_used": F["used"],
                     "row_weights": dict(zip(joints, w.tolist())),
                     "offset_variance_inflation": dict(zip(joints, map(float, inflation))),
                     "n_blocks": F["nb"], "residual_variance_factor": F["s2"],
                     "mass_without_flagged": float(phi[0]) if excluded.any() else None,
                     "mass_with_flagged": mass_all if excluded.any() else None,
                     "mass_unconstrained": unconstrained_mass(F["system"], phi, com_arr)},
    )

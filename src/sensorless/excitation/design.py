"""Optimised excitation: Fourier coefficients that make the base regressor well conditioned.

Each coordinate follows the finite Fourier series of :class:`~sensorless.excitation.FourierTrajectory`
(H harmonics of the base frequency f₀, centre q0). The coefficients x = (a, b, q0) are
chosen to minimise, over N samples of one period,

* ``"cond"``: log cond(W₁ D), the condition number of the *column-equilibrated* base
  regressor (W₁ = W[:, :, independent] stacked over samples and rows, D = diag(‖W₁ col‖)⁻¹),
  i.e. the figure ``identify`` reports as ``diagnostics["condition_number"]``; equilibration
  makes it independent of the parameters' units (kg, kg·m, kg·m², N·m·s);
* ``"dopt"``: −log det(W₁ᵀ W₁ / N), D-optimality (maximal information; unit-independent
  up to a constant).

Limits are hard constraints on the analytic worst-case bounds (triangle inequality over the
harmonics with amplitude √(a² + b²)), which guarantee them at every instant, not only at
samples:

    q0 ± Σ_l amp_l / ω_l ∈ [lower, upper],   Σ_l amp_l ≤ v_max,   Σ_l ω_l amp_l ≤ a_max.

Optional Cartesian boxes (e.g. a tool frame's height above a table) are imposed on the
samples, with Jacobians from Pinocchio. With ``start_at_rest`` the trajectory has zero
velocity and acceleration at t = 0 (Σ_l a_l = 0, Σ_l ω_l b_l = 0), so it can start from
standstill. The problem is solved by SLSQP from a random start (the *random baseline*,
scaled to the same limits); the objective's gradient is by forward differences, each
perturbation costing one batched regressor evaluation. Coulomb terms are smoothed
(tanh(v/ε)) inside the objective so the finite differences are meaningful.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

from ..data import Trajectory, write_npz
from ..errors import ExcitationError, RobotModelError
from ..identification.base import base_parameters
from ..identification.result import versions, write_json_atomic
from .criteria import CRITERIA, _evaluate, _neg_logdet, excitation_metrics
from .fourier import FourierTrajectory
from .limits import (
    CartesianBox,
    ExcitationLimits,
    check_export,
    check_sampled_limits,
    random_excitation,
    robot_limits,
)

__all__ = ["ExcitationDesign", "design_excitation"]


# ---- kinematics for Cartesian constraints ---------------------------------------------------
def _kinematics(structure):
    """(model, data, θ → Pinocchio q, P) with v_tree = P θ̇ for a ModelStructure or TransmissionStructure."""
    if structure.robot.transmission_matrix is not None:  # coordinates θ of a tree q = Gθ + q₀ (TransmissionStructure)
        tree = structure.robot.tree
        idx = [tree.v_index(j) for j in tree.joint_names]
        P = np.zeros((tree.nv, structure.G.shape[1]))
        P[idx] = structure.G
        return tree.model, tree.model.createData(), lambda th: tree.full_configuration(structure.joint_values(th)), P
    robot = structure.robot
    if robot.floating_base:
        raise ExcitationError("Cartesian excitation constraints need a fixed-base robot")
    P = np.zeros((robot.nv, len(robot.joint_names)))
    for k, j in enumerate(robot.joint_names):
        P[robot.v_index(j), k] = 1.0
    return robot.model, robot.model.createData(), robot.full_configuration, P


class _Problem:
    """Variables x = [a (n·H), b (n·H), q0 (n)]; q, v, v̇ are linear in x."""

    def __init__(self, structure, limits, harmonics, base_freq, n_samples, criterion, cartesian, smoothing):
        self.s = copy.copy(structure)
        if getattr(self.s, "coulomb_smoothing", 0.0) <= 0.0:
            self.s.coulomb_smoothing = smoothing
        self.limits = limits
        self.n, self.H, self.f0 = len(limits.joint_names), harmonics, base_freq
        self.w = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
        self.t = np.arange(n_samples) / (n_samples * base_freq)  # one period, periodic grid
        wt = np.outer(self.t, self.w)
        S, C = np.sin(wt), np.cos(wt)
        # q = q0 + Sq a − Cq b ; v = C a + S b ; v̇ = −Sa a + Ca b  (per joint, (N, H) bases)
        self.Bq = (S / self.w, -C / self.w)
        self.Bv = (C, S)
        self.Ba = (-S * self.w, C * self.w)
        self.ind = base_parameters(self.s).independent
        self.criterion = criterion
        self.cartesian = list(cartesian)
        if self.cartesian:
            self.model, self.data, self.to_q, self.P = _kinematics(self.s)
            self.fids = []
            for box in self.cartesian:
                if not self.model.existFrame(box.frame):
                    raise RobotModelError(f"unknown frame '{box.frame}' in a Cartesian excitation constraint")
                self.fids.append(self.model.getFrameId(box.frame))
            self.cart_idx = np.arange(0, n_samples, max(1, n_samples // 100))
        self.n_eval = 0

    # variables
    @property
    def nx(self) -> int:
        return self.n * (2 * self.H + 1)

    def pack(self, traj: FourierTrajectory) -> np.ndarray:
        return np.concatenate([traj.a.ravel(), traj.b.ravel(), traj.q0])

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nH = self.n * self.H
        return x[:nH].reshape(self.n, self.H), x[nH : 2 * nH].reshape(self.n, self.H), x[2 * nH :]

    def fourier(self, x: np.ndarray) -> FourierTrajectory:
        a, b, q0 = self.unpack(x)
        return FourierTrajectory(self.f0, a.copy(), b.copy(), q0.copy(), self.limits.joint_names)

    def states(self, x: np.ndarray):
        a, b, q0 = self.unpack(x)
        q = q0 + self.Bq[0] @ a.T + self.Bq[1] @ b.T
        v = self.Bv[0] @ a.T + self.Bv[1] @ b.T
        acc = self.Ba[0] @ a.T + self.Ba[1] @ b.T
        return q, v, acc

    # objective
    def _base_regressor(self, q, v, a) -> np.ndarray:
        """W₁ stacked over samples and rows, (N·rows, r); q, v, a may carry a leading batch axis."""
        n = q.shape[-1]
        W = _evaluate(self.s, q.reshape(-1, n), v.reshape(-1, n), a.reshape(-1, n))[:, :, self.ind]
        self.n_eval += W.shape[0]
        return W.reshape(q.shape[:-2] + (-1, W.shape[-1]))

    def _crit(self, X: np.ndarray) -> tuple[float, Callable[[np.ndarray], np.ndarray]]:
        """Criterion of W₁ = X (m × r) and its exact directional derivative d(dX) for a batch
        of directions dX (K, m, r), by first-order eigenvalue / log-det perturbation:

        * cond: X̃ = X C⁻¹ (C = column norms), λ = uᵀX̃ᵀX̃u ⇒ dλ = 2 (X̃u)ᵀ dX̃ u with
          dX̃ = dX C⁻¹ − X C⁻² dC, dC_i = X_iᵀ dX_i / C_i; d log cond = ½ (dλ_max/λ_max − dλ_min/λ_min);
        * dopt: −log det(XᵀX/m) ⇒ −2 ⟨X (XᵀX)⁻¹, dX⟩.
        """
        M = X.T @ X
        if self.criterion == "dopt":
            f = float(_neg_logdet(M, X.shape[0]))
            try:
                Z = X @ np.linalg.inv(M)
            except np.linalg.LinAlgError:
                Z = X @ np.linalg.pinv(M)
            return f, lambda dX: -2.0 * np.einsum("mr,kmr->k", Z, dX)
        c = np.sqrt(np.maximum(np.diag(M), 1e-300))
        Ms = M / np.outer(c, c)
        ev, U = np.linalg.eigh(Ms)
        lmin, lmax = max(ev[0], 1e-300 * ev[-1]), ev[-1]
        f = 0.5 * float(np.log(lmax) - np.log(lmin))
        parts = []
        for lam, u in ((lmax, U[:, -1]), (lmin, U[:, 0])):
            y = X @ (u / c)  # X̃u
            parts.append((lam, u / c, X.T @ y, y))

        def directional(dX: np.ndarray) -> np.ndarray:
            dc = np.einsum("mr,kmr->kr", X, dX) / c  # (K, r)
            out = np.zeros(dX.shape[0])
            for sign, (lam, uc, Xty, y) in zip((0.5, -0.5), parts):
                dlam = 2.0 * (np.einsum("m,kmr,r->k", y, dX, uc) - (dc / c) @ (uc * Xty))
                out += sign * dlam / lam
            return out

        return f, directional

    def value(self, x: np.ndarray) -> float:
        return self._crit(self._base_regressor(*self.states(x)))[0]

    def value_and_grad(self, x: np.ndarray, h: float = 1e-6) -> tuple[float, np.ndarray]:
        """Criterion and gradient: dW₁/dx_k by forward differences of the regressor (one batched
        evaluation per joint), chained with the exact derivative of the criterion in W₁."""
        q, v, a = self.states(x)
        X = self._base_regressor(q, v, a)
        f0, directional = self._crit(X)
        g = np.zeros_like(x)
        nH, N = self.n * self.H, len(self.t)
        dq = np.concatenate([self.Bq[0].T, self.Bq[1].T, np.ones((1, N))]) * h
        dv = np.concatenate([self.Bv[0].T, self.Bv[1].T, np.zeros((1, N))]) * h
        da = np.concatenate([self.Ba[0].T, self.Ba[1].T, np.zeros((1, N))]) * h
        K = dq.shape[0]
        for j in range(self.n):
            # perturbations of joint j: H of a, H of b, 1 of q0 → K = 2H + 1 trajectories
            Q, V, A = (np.repeat(z[None], K, axis=0) for z in (q, v, a))
            Q[:, :, j] += dq
            V[:, :, j] += dv
            A[:, :, j] += da
            dX = (self._base_regressor(Q, V, A) - X[None]) / h
            idx = np.concatenate([j * self.H + np.arange(self.H), nH + j * self.H + np.arange(self.H), [2 * nH + j]])
            g[idx] = directional(dX)
        if not (np.isfinite(f0) and np.all(np.isfinite(g))):
            g = np.nan_to_num(g, nan=0.0, posinf=0.0, neginf=0.0)
        return f0, g

    # constraints: c(x) ≥ 0
    def _amp(self, x):
        a, b, _ = self.unpack(x)
        return a, b, np.sqrt(a * a + b * b + 1e-12)

    def limit_constraints(self, x: np.ndarray) -> np.ndarray:
        _, _, q0 = self.unpack(x)
        _, _, amp = self._amp(x)
        L = self.limits
        dq, dv, da = amp @ (1 / self.w), amp.sum(axis=1), amp @ self.w
        return np.concatenate([q0 - dq - L.lower, L.upper - q0 - dq, L.velocity - dv, L.acceleration - da])

    def limit_jacobian(self, x: np.ndarray) -> np.ndarray:
        a, b, amp = self._amp(x)
        n, H = self.n, self.H
        nH = n * H
        J = np.zeros((4 * n, self.nx))
        for weights, block, sign_q0 in ((1 / self.w, 0, 1.0), (1 / self.w, 1, -1.0), (np.ones(H), 2, 0.0), (self.w, 3, 0.0)):
            for j in range(n):
                r = block * n + j
                J[r, j * H : (j + 1) * H] = -weights * a[j] / amp[j]
                J[r, nH + j * H : nH + (j + 1) * H] = -weights * b[j] / amp[j]
                J[r, 2 * nH + j] = sign_q0
        return J

    def rest_constraints(self, x: np.ndarray) -> np.ndarray:
        a, b, _ = self.unpack(x)
        return np.concatenate([a.sum(axis=1), b @ self.w])

    def rest_jacobian(self, x: np.ndarray) -> np.ndarray:
        n, H = self.n, self.H
        J = np.zeros((2 * n, self.nx))
        for j in range(n):
            J[j, j * H : (j + 1) * H] = 1.0
            J[n + j, n * H + j * H : n * H + (j + 1) * H] = self.w
        return J

    def _cartesian(self, x: np.ndarray, jac: bool):
        q, _, _ = self.states(x)
        idx = self.cart_idx
        Qp = self.to_q(q[idx])
        vals, rows = [], []
        nH = self.n * self.H
        for box, fid in zip(self.cartesian, self.fids):
            lo, hi = np.asarray(box.lower, float), np.asarray(box.upper, float)
            for k, i in enumerate(idx):
                pin.framesForwardKinematics(self.model, self.data, Qp[k])
                p = self.data.oMf[fid].translation
                if jac:
                    Jf = pin.computeFrameJacobian(self.model, self.data, Qp[k], fid, pin.LOCAL_WORLD_ALIGNED)[:3] @ self.P
                for ax in range(3):
                    for sign, bound in ((1.0, lo[ax]), (-1.0, hi[ax])):
                        if not np.isfinite(bound):
                            continue
                        vals.append(sign * (p[ax] - bound))
                        if jac:
                            r = np.zeros(self.nx)
                            dth = sign * Jf[ax]  # (n,)
                            for j in range(self.n):
                                r[j * self.H : (j + 1) * self.H] = dth[j] * self.Bq[0][i]
                                r[nH + j * self.H : nH + (j + 1) * self.H] = dth[j] * self.Bq[1][i]
                                r[2 * nH + j] = dth[j]
                            rows.append(r)
        return np.array(vals), (np.array(rows) if jac else None)

    def cartesian_constraints(self, x):
        return self._cartesian(x, False)[0]

    def cartesian_jacobian(self, x):
        return self._cartesian(x, True)[1]


@dataclass
class ExcitationDesign:
    """An optimised excitation and its figures (see :func:`design_excitation`)."""

    trajectory: FourierTrajectory
    limits: ExcitationLimits
    criterion: str
    metrics: dict  # optimised trajectory, on the evaluation grid
    random_metrics: dict  # the random start (same limits, same seed), same grid
    limit_violation: dict  # on a dense grid; ≤ 0 everywhere means every limit holds
    cartesian: list[CartesianBox] = field(default_factory=list)
    cartesian_violation: float | None = None
    settings: dict = field(default_factory=dict)
    random_trajectory: FourierTrajectory | None = None
    hard_limits: dict | None = None  # the robot model's own limits (:func:`robot_limits`)

    @property
    def improvement(self) -> float:
        """cond(random, same seed) / cond(optimised), both column-equilibrated."""
        return self.random_metrics["cond"] / self.metrics["cond"]

    @property
    def improvement_median(self) -> float:
        """median cond(random over seeds) / cond(optimised)."""
        return self.random_metrics["cond_median"] / self.metrics["cond"]

    def sample(self, rate: float, periods: float = 1.0) -> Trajectory:
        return self.trajectory.sample(rate, periods * self.trajectory.period)

    def to_dict(self) -> dict:
        return {
            "trajectory": self.trajectory.to_dict(),
            "limits": self.limits.to_dict(),
            "criterion": self.criterion,
            "criterion_value": self.metrics["cond"] if self.criterion == "cond" else self.metrics["neg_logdet"],
            "metrics": self.metrics,
            "random_baseline": {"metrics": self.random_metrics, "trajectory": self.random_trajectory.to_dict() if self.random_trajectory else None},
            "improvement_cond": self.improvement,
            "improvement_cond_median": self.improvement_median,
            "limit_violation": self.limit_violation,
            "robot_limits": self.hard_limits,
            "cartesian": [c.to_dict() for c in self.cartesian],
            "cartesian_violation": self.cartesian_violation,
            "settings": self.settings,
            "versions": versions(),
        }

    def save(self, outdir: str | Path, rate: float = 200.0, periods: float = 1.0) -> tuple[Path, Path]:
        """Write ``excitation.json`` (coefficients, limits, criterion, figures) and
        ``trajectory.npz`` (q, v, a sampled at ``rate`` for ``periods`` periods).

        The samples written are checked first (:func:`check_sampled_limits`, against the
        excitation limits and the robot model's): a violation raises and nothing is written.
        """
        check_export(rate, periods, self.trajectory.a.shape[1], self.trajectory.base_freq)
        traj = self.sample(rate, periods)
        excess = check_sampled_limits(traj, self.limits, self.hard_limits)
        outdir = Path(outdir)
        outdir.mkdir(parents=True, exist_ok=True)
        doc = self.to_dict()
        doc["export"] = {"rate_hz": rate, "periods": periods, "n_samples": len(traj), "sampled_limit_excess": excess}
        write_json_atomic(doc, outdir / "excitation.json")
        npz = write_npz(traj, outdir / "trajectory.npz")
        return outdir / "excitation.json", npz


def design_excitation(
    structure,
    limits: ExcitationLimits | None = None,
    *,
    harmonics: int = 5,
    base_freq: float = 0.1,
    criterion: str = "cond",
    n_samples: int = 200,
    cartesian: Sequence[CartesianBox] = (),
    start_at_rest: bool = False,
    seed: int = 0,
    maxiter: int = 100,
    coulomb_smoothing: float = 0.05,
    eval_rate: float | None = None,
    n_random: int = 10,
    progress: Callable[[int, float], None] | None = None,
) -> ExcitationDesign:
    """Optimise a Fourier excitation for ``structure`` (a ModelStructure or TransmissionStructure).

    ``limits`` default to :meth:`ExcitationLimits.from_robot` of ``structure.robot``. The
    optimiser starts from :func:`random_excitation` (``seed``, 90 % of the limits, projected
    to start at rest when asked). The *random baseline* is :func:`random_excitation` with
    ``seed`` at 100 % of the same limits (for a Robot, exactly
    :func:`~sensorless.excitation.random_fourier`), plus the median over ``n_random`` seeds
    (``seed … seed + n_random − 1``). Figures are evaluated on one period sampled at
    ``eval_rate`` (default ``max(n_samples·f0, 20 × highest harmonic)`` Hz); limits are
    checked on a 4× denser grid. ``progress(iteration, criterion)`` is called after each
    SLSQP iteration.
    """
    if criterion not in CRITERIA:
        raise ExcitationError(f"unknown criterion '{criterion}'; choose from {CRITERIA}")
    if not (harmonics >= 1 and np.isfinite(base_freq) and base_freq > 0 and n_samples >= 4):
        raise ExcitationError(f"need harmonics >= 1, base_freq > 0 and n_samples >= 4 (got {harmonics}, {base_freq}, {n_samples})")
    robot = structure.robot
    if robot.floating_base:
        raise ExcitationError(f"{robot.name}: excitation design needs a fixed-base robot (or a TransmissionStructure)")
    limits = ExcitationLimits.from_robot(robot) if limits is None else limits
    if tuple(limits.joint_names) != tuple(robot.joint_names):
        raise ExcitationError(f"limits are for joints {list(limits.joint_names)}, the structure moves {list(robot.joint_names)}")
    hard = robot_limits(robot)
    for j, name in enumerate(limits.joint_names):
        for what, val, lim, bad in (
            ("lower position", limits.lower[j], hard["lower"][j], limits.lower[j] < hard["lower"][j] - 1e-12),
            ("upper position", limits.upper[j], hard["upper"][j], limits.upper[j] > hard["upper"][j] + 1e-12),
            ("velocity", limits.velocity[j], hard["velocity"][j], limits.velocity[j] > hard["velocity"][j] + 1e-12),
        ):
            if bad:
                raise ExcitationError(f"excitation {what} limit {val:.6g} of joint {name} lies outside the robot model's ({lim:.6g})")
    t0 = time.perf_counter()
    prob = _Problem(structure, limits, harmonics, base_freq, n_samples, criterion, cartesian, coulomb_smoothing)
    start = random_excitation(limits, harmonics=harmonics, base_freq=base_freq, rng=seed, start_at_rest=start_at_rest, fill=0.9)
    x0 = prob.pack(start)
    cons = [{"type": "ineq", "fun": prob.limit_constraints, "jac": prob.limit_jacobian}]
    if start_at_rest:
        cons.append({"type": "eq", "fun": prob.rest_constraints, "jac": prob.rest_jacobian})
    if cartesian:
        # shrink the start towards its centre until it is inside the Cartesian boxes
        for _ in range(8):
            c0 = prob.cartesian_constraints(x0)
            if np.all(c0 >= 0):
                break
            nH = prob.n * prob.H
            x0 = x0.copy()
            x0[: 2 * nH] *= 0.5
        else:
            raise ExcitationError(
                f"the centre of the joint limits violates a Cartesian constraint by {-c0.min():.3g} m; "
                "widen the box or give joint limits whose centre satisfies it"
            )
        cons.append({"type": "ineq", "fun": prob.cartesian_constraints, "jac": prob.cartesian_jacobian})
    cache: dict = {}

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = prob.value_and_grad(x)
        return cache[key][0]

    def jac(x):
        fun(x)
        return cache[x.tobytes()][1]

    it = [0]

    def callback(xk):
        it[0] += 1
        if progress is not None:
            progress(it[0], fun(xk))

    res = minimize(fun, x0, jac=jac, method="SLSQP", constraints=cons, callback=callback,
                   options={"maxiter": maxiter, "ftol": 1e-6})
    x = res.x
    # SLSQP may end marginally outside the (analytic) limits: shrink amplitudes to be exact
    opt = _fit_if_needed(prob.fourier(x), limits)
    if prob.value(prob.pack(opt)) > prob.value(x0):  # never return worse than the start
        opt = prob.fourier(x0)
    seconds = time.perf_counter() - t0

    rate = eval_rate or max(n_samples * base_freq, 20.0 * harmonics * base_freq)
    grid = np.arange(round(rate / base_freq)) / rate
    ind = prob.ind
    baseline = random_excitation(limits, harmonics=harmonics, base_freq=base_freq, rng=seed)
    metrics = excitation_metrics(prob.s, *opt.evaluate(grid), independent=ind)
    random_metrics = excitation_metrics(prob.s, *baseline.evaluate(grid), independent=ind)
    conds = [random_metrics["cond"]] + [
        excitation_metrics(prob.s, *random_excitation(limits, harmonics=harmonics, base_freq=base_freq, rng=seed + k).evaluate(grid), independent=ind)["cond"]
        for k in range(1, max(n_random, 1))
    ]
    random_metrics["cond_median"] = float(np.median(conds))
    random_metrics["cond_all_seeds"] = [float(c) for c in conds]
    if getattr(structure, "coulomb_smoothing", 0.0) != prob.s.coulomb_smoothing:  # the structure's own (sign) terms too
        metrics["cond_unsmoothed"] = excitation_metrics(structure, *opt.evaluate(grid), independent=ind)["cond"]
        random_metrics["cond_unsmoothed"] = excitation_metrics(structure, *baseline.evaluate(grid), independent=ind)["cond"]
    dense = np.arange(4 * len(grid)) / (4 * rate)
    violation = limits.violation(*opt.evaluate(dense))
    cart_v = None
    if cartesian:
        prob.cart_idx = np.arange(n_samples)
        cart_v = float(-prob.cartesian_constraints(prob.pack(opt)).min())
    settings = {
        "harmonics": harmonics,
        "base_freq": base_freq,
        "criterion": criterion,
        "objective": "log cond of the column-equilibrated base regressor" if criterion == "cond" else "-log det(W1'W1/N)",
        "n_samples": n_samples,
        "eval_rate_hz": rate,
        "start_at_rest": start_at_rest,
        "seed": seed,
        "maxiter": maxiter,
        "iterations": int(res.nit),
        "optimizer": "scipy SLSQP",
        "optimizer_status": int(res.status),
        "optimizer_message": str(res.message),
        "coulomb_smoothing_in_objective": prob.s.coulomb_smoothing,
        "regressor_evaluations": prob.n_eval,
        "seconds": seconds,
        "n_base_parameters": len(ind),
        "structure": structure.settings(),
    }
    settings["n_random"] = len(conds)
    return ExcitationDesign(opt, limits, criterion, metrics, random_metrics, violation, list(cartesian), cart_v, settings, baseline,
                            hard_limits=hard)


def _fit_if_needed(traj: FourierTrajectory, limits: ExcitationLimits) -> FourierTrajectory:
    """Scale amplitudes down (and clip q0) where the analytic bounds exceed the limits."""
    dq, dv, da = traj.bounds()
    q0 = np.clip(traj.q0, limits.lower, limits.upper)
    room = np.minimum(q0 - limits.lower, limits.upper - q0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.min(np.stack([room / dq, limits.velocity / dv, limits.acceleration / da]), axis=0)
    s = np.where(np.isfinite(s), np.minimum(s, 1.0), 1.0)
    return FourierTrajectory(traj.base_freq, traj.a * s[:, None], traj.b * s[:, None], q0, traj.joint_names)

"""Identification of the actuator model Δq = Kτ τ + Kv q̇ (+ Kc sgn q̇), joint by joint.

Inputs are arrays (N, n_joints) of joint torque τ (e.g. from the F/T + IMU estimator),
joint velocity q̇ and command offset Δq = q_cmd − q (or motor current: the maths is the
same with Δq replaced by i). Four fits:

* :func:`fit_least_squares` — ordinary least squares.
* :func:`fit_piecewise_linear` — per sign of q̇, a continuous three-segment function of τ
  (plus Kv q̇); breakpoints updated iteratively (Gauss–Newton / Muggeo step), central
  slope constrained to a box.
* :func:`fit_asymmetric` — penalty Φ(z) = w z² if z > 0 (over-estimation of |Δq|),
  z² otherwise, z = sgn(Δq)(x·θ − Δq). Φ is convex and piecewise quadratic; Newton's
  method (:func:`asymmetric_least_squares`) converges in a handful of O(N) passes.
* :func:`fit_two_stage` — Kτ from near-zero-velocity samples, then Kv (and Kc) from the
  rest.

and :func:`fit_current_model` for τ = K1 i − Fv q̇ − Fc sgn(q̇).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ExcitationError, NonFiniteError, ShapeMismatchError, SolverError
from .model import (
    CurrentModel,
    MotorModel,
    PiecewiseLinearModel,
    joint_names_or_default,
    over_estimation_fraction,
)

__all__ = [
    "AsymmetricSolution",
    "unsaturated",
    "asymmetric_least_squares",
    "fit_asymmetric",
    "fit_current_model",
    "fit_least_squares",
    "fit_piecewise_linear",
    "fit_two_stage",
]


# ---- input checks ------------------------------------------------------------------
def _prepare(arrays: dict[str, np.ndarray], joint_names: Sequence[str],
             valid=None) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """Check shapes and finiteness; ``out["valid"]`` is the (N, n) mask of samples to fit
    (``valid``: None = all, (N,) or (N, n) bool, e.g. from :func:`unsaturated`)."""
    out = {}
    shape = None
    for name, a in arrays.items():
        a = np.asarray(a, dtype=float)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise ShapeMismatchError(f"{name} must be (N, n_joints), got shape {a.shape}")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise ShapeMismatchError(f"{name} has shape {a.shape}, expected {shape} like {next(iter(arrays))}")
        bad = ~np.isfinite(a)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise NonFiniteError(f"{name} has a non-finite value at sample {i}, column {j}")
        out[name] = a
    n = shape[1]
    names = joint_names_or_default(joint_names, n, "columns")
    if valid is None:
        out["valid"] = np.ones(shape, bool)
    else:
        v = np.asarray(valid, dtype=bool)
        v = np.broadcast_to(v[:, None] if v.ndim == 1 else v, shape) if v.shape[0] == shape[0] else None
        if v is None:
            raise ShapeMismatchError(f"valid mask has shape {np.shape(valid)}, expected ({shape[0]},) or {shape}")
        out["valid"] = np.ascontiguousarray(v)
    return out, names


def _joint_columns(a: dict[str, np.ndarray], *keys: str) -> Iterator[tuple]:
    """For each joint j of :func:`_prepare`'s arrays ``a``: ``(j, a[k][valid, j] for k in keys)``,
    the samples of column j that its fit uses."""
    for j in range(a["valid"].shape[1]):
        m = a["valid"][:, j]
        yield (j, *(a[k][m, j] for k in keys))


def unsaturated(command, limit, margin: float = 0.98) -> np.ndarray:
    """(N, n) mask of samples whose drive command (current or motor torque) is below
    ``margin`` × its ``limit`` in magnitude. Saturated samples break Δq = Kτ τ + …: the
    position error keeps growing while the torque does not, so fits should drop them."""
    c = np.atleast_2d(np.asarray(command, dtype=float))
    lim = np.broadcast_to(np.asarray(limit, dtype=float), c.shape[1:])
    if np.any(lim <= 0):
        raise ShapeMismatchError(f"saturation limits must be positive, got {lim}")
    return np.abs(c) < margin * lim


def _check_rank(X: np.ndarray, joint: str, what: str) -> None:
    if X.shape[0] < X.shape[1] + 1:
        raise ExcitationError(f"joint '{joint}': {X.shape[0]} samples are too few to fit {what}")
    s = np.linalg.svd(X / np.maximum(np.abs(X).max(axis=0), 1e-300), compute_uv=False)
    if s[-1] < 1e-9 * s[0]:
        raise ExcitationError(f"joint '{joint}': the data do not excite every term of {what} (rank deficient)")


def _features(tau: np.ndarray, dq: np.ndarray, coulomb: bool) -> np.ndarray:
    cols = [tau, dq] + ([np.sign(dq)] if coulomb else [])
    return np.column_stack(cols)


def _scaled_lstsq(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    sc = np.maximum(np.sqrt((X * X).mean(axis=0)), 1e-300)
    theta, *_ = np.linalg.lstsq(X / sc, y, rcond=None)
    return theta / sc


# ---- asymmetric least squares: the Newton solver -------------------------------------
@dataclass
class AsymmetricSolution:
    """What :func:`asymmetric_least_squares` returns: the estimate θ, the Newton iterations and whether they
    converged, the fraction of over-estimated samples, the objective and the wall time [s]."""

    theta: np.ndarray
    iterations: int
    converged: bool
    over_fraction: float
    objective: float
    seconds: float

    def to_dict(self) -> dict:
        return {"theta": self.theta.tolist(), "iterations": self.iterations, "converged": self.converged,
                "over_fraction": self.over_fraction, "objective": self.objective, "seconds": self.seconds}


def asymmetric_least_squares(
    X: np.ndarray,
    y: np.ndarray,
    weight: float = 100.0,
    sign: np.ndarray | None = None,
    max_iter: int = 100,
) -> AsymmetricSolution:
    """min_θ Σ ω_i r_i², r = Xθ − y, ω_i = ``weight`` if s_i r_i > 0 else 1, s = sgn(y) (0 → +1).

    The objective is convex, C¹ and piecewise quadratic (expectile regression). Newton's
    step is the weighted-least-squares solution for the current active set
    P = {i : s_i r_i > 0}: with the Gram matrix G = XᵀX computed once,

        H = G + (w − 1) X_Pᵀ X_P,   g = Xᵀ r + (w − 1) X_Pᵀ r_P,   θ ← θ − H⁻¹ g,

    i.e. a few O(N p) passes per iteration (only the small set P is gathered), in
    preallocated buffers. If a full step does not decrease the objective, an exact line
    search is done on the monotone, piecewise-linear derivative (Illinois regula falsi).
    The iteration stops when the active set no longer changes: θ then satisfies the
    optimality conditions exactly. ``X`` may be C- or Fortran-ordered; Fortran order
    (columns contiguous) avoids one copy.
    """
    X = np.asarray(X, dtype=float)
    y = np.ascontiguousarray(y, dtype=float).ravel()
    if X.ndim != 2 or X.shape[0] != y.size:
        raise ShapeMismatchError(f"X is {X.shape}, y has {y.size} samples")
    if not weight > 0:
        raise SolverError(f"asymmetric weight must be positive, got {weight}")
    t0 = time.perf_counter()
    XT = np.ascontiguousarray(X.T)  # (p, N): contiguous columns
    p, n = XT.shape
    pos = (y >= 0) if sign is None else (np.asarray(sign, float).ravel() > 0)
    sc = np.maximum(np.sqrt(np.einsum("ij,ij->i", XT, XT) / n), 1e-300)
    G = (XT @ XT.T) / np.outer(sc, sc)
    wm1 = weight - 1.0
    r, r_old, tmp = np.empty(n), np.empty(n), np.empty(n)
    m1, mask = np.empty(n, bool), np.empty(n, bool)

    def residual(theta, out):  # out = X theta - y, with theta in unscaled units
        np.multiply(XT[0], theta[0], out=out)
        for k in range(1, p):
            np.multiply(XT[k], theta[k], out=tmp)
            out += tmp
        out -= y
        return out

    def active(res):
        np.greater(res, 0.0, out=m1)
        np.equal(m1, pos, out=mask)
        return np.flatnonzero(mask)

    def objective(res, P):
        rp = res[P]
        return float(res @ res + wm1 * (rp @ rp))

    th = np.linalg.solve(G, (XT @ y) / sc)  # scaled ordinary least squares start
    residual(th / sc, r)
    P = active(r)
    f = objective(r, P)
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        XP = np.take(XT, P, axis=1) / sc[:, None]
        H = G + wm1 * (XP @ XP.T)
        g = (XT @ r) / sc + wm1 * (XP @ r[P])
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            raise SolverError("asymmetric least squares: singular Hessian (regressors not excited)") from None
        r, r_old = r_old, r
        residual((th + step) / sc, r)
        P_new = active(r)
        f_new = objective(r, P_new)
        if f_new > f * (1 + 1e-12):  # exact line search on φ'(α) = 2 Σ ω(α) (r + α d) d
            d = r - r_old
            alpha = _line_search(r_old, d, pos, wm1)
            step = alpha * step
            residual((th + step) / sc, r)
            P_new = active(r)
            f_new = objective(r, P_new)
        th = th + step
        same = P_new.size == P.size and np.array_equal(P_new, P)
        P, f = P_new, f_new
        if same:
            converged = True
            break
    return AsymmetricSolution(th / sc, it, converged, float(P.size / n), f, time.perf_counter() - t0)


def _line_search(r: np.ndarray, d: np.ndarray, pos: np.ndarray, wm1: float) -> float:
    def dphi(a):
        z = r + a * d
        w = 1.0 + wm1 * ((z > 0) == pos)
        return float(np.sum(w * z * d))

    lo, hi = 0.0, 1.0
    flo, fhi = dphi(lo), dphi(hi)
    while fhi < 0 and hi < 1e6:
        lo, flo, hi = hi, fhi, 2 * hi
        fhi = dphi(hi)
    side = 0
    a = hi
    for _ in range(60):
        a = (lo * fhi - hi * flo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        fa = dphi(a)
        if abs(fa) <= 1e-14 * (abs(flo) + abs(fhi)) or hi - lo < 1e-15:
            break
        if fa < 0:
            lo, flo = a, fa
            if side == -1:
                fhi /= 2
            side = -1
        else:
            hi, fhi = a, fa
            if side == 1:
                flo /= 2
            side = 1
    return a


# ---- fits -------------------------------------------------------------------------------
def _masked_metrics(pred, y, valid) -> tuple[np.ndarray, np.ndarray]:
    """Per-column over-estimation fraction and RMSE over the ``valid`` samples."""
    cnt = np.maximum(valid.sum(axis=0), 1)
    over = over_estimation_fraction(pred, y, valid)
    rmse = np.sqrt((np.where(valid, pred - y, 0.0) ** 2).sum(axis=0) / cnt)
    return over, rmse


def _motor_model(P: np.ndarray, names, a: dict[str, np.ndarray], coulomb: bool, extra: list[dict], method: str,
                 info: dict | None = None) -> MotorModel:
    """The :class:`MotorModel` of per-joint rows ``P`` = (Kτ, Kv, Kc), its info completed with the
    fit's metrics on :func:`_prepare`'s arrays ``a`` (and ``extra``, one dict per joint)."""
    model = MotorModel(P[:, 0], P[:, 1], P[:, 2], joint_names=names, method=method, info=info or {})
    valid = a["valid"]
    pred = model.delta_q(a["tau"], a["dq"], coulomb=coulomb)
    over, rmse = _masked_metrics(pred, a["delta_q"], valid)
    model.info = {
        "n_samples": int(a["tau"].shape[0]),
        "n_valid": dict(zip(model.joint_names, valid.sum(axis=0).tolist())),
        "coulomb": coulomb,
        "over_estimation_fraction": dict(zip(model.joint_names, over.tolist())),
        "rmse": dict(zip(model.joint_names, rmse.tolist())),
        **({"per_joint": dict(zip(model.joint_names, extra))} if extra else {}),
        **model.info,
    }
    return model


def _unpack(theta: np.ndarray, coulomb: bool) -> tuple[float, float, float]:
    return float(theta[0]), float(theta[1]), float(theta[2]) if coulomb else 0.0


def fit_least_squares(tau, dq, delta_q, coulomb: bool = False, joint_names: Sequence[str] = (),
                      valid=None) -> MotorModel:
    """Ordinary least squares of Δq on [τ, q̇ (, sgn q̇)] per joint (``valid``: see :func:`_prepare`)."""
    a, names = _prepare({"tau": tau, "dq": dq, "delta_q": delta_q}, joint_names, valid)
    P = np.zeros((len(names), 3))
    for j, t, v, y in _joint_columns(a, "tau", "dq", "delta_q"):
        X = _features(t, v, coulomb)
        _check_rank(X, names[j], "Δq = Kτ τ + Kv q̇" + (" + Kc sgn q̇" if coulomb else ""))
        P[j] = _unpack(_scaled_lstsq(X, y), coulomb)
    return _motor_model(P, names, a, coulomb, [], "least_squares")


def fit_asymmetric(
    tau, dq, delta_q, weight: float = 100.0, coulomb: bool = False, joint_names: Sequence[str] = (), valid=None
) -> MotorModel:
    """Asymmetric-penalty fit (over-estimation of |Δq| weighted ``weight`` times), per joint."""
    a, names = _prepare({"tau": tau, "dq": dq, "delta_q": delta_q}, joint_names, valid)
    P = np.zeros((len(names), 3))
    extra = []
    for j, t, v, y in _joint_columns(a, "tau", "dq", "delta_q"):
        X = _features(t, v, coulomb)
        _check_rank(X, names[j], "the asymmetric motor model")
        sol = asymmetric_least_squares(X, y, weight)
        if not sol.converged:
            raise SolverError(f"joint '{names[j]}': asymmetric fit did not converge in {sol.iterations} Newton steps")
        P[j] = _unpack(sol.theta, coulomb)
        extra.append({"iterations": sol.iterations, "seconds": sol.seconds})
    return _motor_model(P, names, a, coulomb, extra, f"asymmetric(w={weight:g})", {"weight": weight})


def fit_two_stage(
    tau,
    dq,
    delta_q,
    v_threshold: float | Sequence[float] | None = None,
    coulomb: bool = True,
    weight: float = 1.0,
    joint_names: Sequence[str] = (),
    valid=None,
) -> MotorModel:
    """Stage 1: Δq = Kτ τ on samples with |q̇| < v_threshold. Stage 2: Δq − Kτ τ = Kv q̇
    (+ Kc sgn q̇) on the others. ``weight`` > 1 uses the asymmetric penalty in both
    stages. Default threshold: 5 % of the joint's max |q̇|."""
    a, names = _prepare({"tau": tau, "dq": dq, "delta_q": delta_q}, joint_names, valid)
    n = len(names)
    vmax = np.abs(np.where(a["valid"], a["dq"], 0.0)).max(axis=0)
    thr = 0.05 * vmax if v_threshold is None else np.broadcast_to(np.asarray(v_threshold, float), (n,))
    P = np.zeros((n, 3))
    extra = []
    for j, t, v, y in _joint_columns(a, "tau", "dq", "delta_q"):
        slow = np.abs(v) < thr[j]
        if slow.sum() < 10 or (~slow).sum() < 10:
            raise ExcitationError(
                f"joint '{names[j]}': two-stage fit needs ≥ 10 samples below and above |q̇| = {thr[j]:.3g} rad/s "
                f"(got {int(slow.sum())} and {int((~slow).sum())})"
            )
        X1 = t[slow, None]
        _check_rank(X1, names[j], "stage 1 (Kτ)")
        k_tau = float(_solve(X1, y[slow], weight)[0])
        X2 = np.column_stack([v[~slow]] + ([np.sign(v[~slow])] if coulomb else []))
        _check_rank(X2, names[j], "stage 2 (Kv" + (", Kc)" if coulomb else ")"))
        th2 = _solve(X2, y[~slow] - k_tau * t[~slow], weight)
        P[j] = (k_tau, th2[0], th2[1] if coulomb else 0.0)
        extra.append({"v_threshold": float(thr[j]), "n_slow": int(slow.sum()), "n_moving": int((~slow).sum())})
    return _motor_model(P, names, a, coulomb, extra, "two_stage" + (f"(w={weight:g})" if weight != 1 else ""))


def _solve(X: np.ndarray, y: np.ndarray, weight: float) -> np.ndarray:
    if weight == 1.0:
        return _scaled_lstsq(X, y)
    sol = asymmetric_least_squares(X, y, weight)
    return sol.theta


def fit_current_model(current, dq, tau, coulomb: bool = True, joint_names: Sequence[str] = (),
                      valid=None) -> CurrentModel:
    """τ = K1 i − Fv q̇ − Fc sgn(q̇) by least squares, per joint."""
    a, names = _prepare({"current": current, "dq": dq, "tau": tau}, joint_names, valid)
    P = np.zeros((len(names), 3))
    rmse = []
    for j, i, v, t in _joint_columns(a, "current", "dq", "tau"):
        X = np.column_stack([i, -v] + ([-np.sign(v)] if coulomb else []))
        _check_rank(X, names[j], "τ = K1 i − Fv q̇" + (" − Fc sgn q̇" if coulomb else ""))
        th = _scaled_lstsq(X, t)
        P[j] = (th[0], th[1], th[2] if coulomb else 0.0)
        rmse.append(float(np.sqrt(np.mean((X @ th - t) ** 2))))
    return CurrentModel(P[:, 0], P[:, 1], P[:, 2], joint_names=names, method="current_least_squares",
                        info={"n_samples": int(a["tau"].shape[0]), "coulomb": coulomb,
                              "rmse_torque": dict(zip(names, rmse))})


# ---- piecewise linear ----------------------------------------------------------------------
def fit_piecewise_linear(
    tau,
    dq,
    delta_q,
    central_slope: tuple[float | None, float | None] | None = None,
    max_iter: int = 50,
    tol: float = 1e-4,
    joint_names: Sequence[str] = (),
    valid=None,
) -> PiecewiseLinearModel:
    """Per joint and sign of q̇: Δq = f(τ) + Kv q̇ with f continuous, three linear segments.

    Breakpoints b1 < b2 start at the 1/3 and 2/3 quantiles of τ and are updated by the
    Gauss–Newton (Muggeo 2003) step: the regressors −1[τ < b1], −1[τ > b2] are added to the
    linear fit and their coefficients γ give b ← b + γ / Δslope, until the update is below
    ``tol`` × range(τ). The central slope s_mid is kept in ``central_slope`` = (lo, hi)
    (default (0, 3 × the least-squares Kτ)): with a single bounded coefficient in a convex
    least-squares problem the optimum is either the unconstrained one or lies on the
    violated bound, so the constraint is enforced exactly.
    """
    a, names = _prepare({"tau": tau, "dq": dq, "delta_q": delta_q}, joint_names, valid)
    n = len(names)
    shp = (n, 2)
    out = {k: np.zeros(shp) for k in ("c", "s_left", "s_mid", "s_right", "b1", "b2", "k_v")}
    extra = []
    for j, t, v, y in _joint_columns(a, "tau", "dq", "delta_q"):
        if central_slope is None:
            k_ls = _scaled_lstsq(np.column_stack([t, v]), y)[0]
            lo, hi = 0.0, 3.0 * abs(k_ls)
        else:
            lo = -np.inf if central_slope[0] is None else central_slope[0]
            hi = np.inf if central_slope[1] is None else central_slope[1]
        info_j = {}
        for k, mask in enumerate((v >= 0, v < 0)):
            label = "dq>=0" if k == 0 else "dq<0"
            if mask.sum() < 30:
                raise ExcitationError(f"joint '{names[j]}': only {int(mask.sum())} samples with {label}; need ≥ 30")
            p, it, conv = _pwl_one(t[mask], v[mask], y[mask], lo, hi, max_iter, tol, f"joint '{names[j]}' ({label})")
            for key, val in p.items():
                out[key][j, k] = val
            info_j[label] = {"iterations": it, "converged": conv, "n": int(mask.sum())}
        extra.append(info_j)
    model = PiecewiseLinearModel(**out, joint_names=names, info={"central_slope_bounds": central_slope})
    pred = model.delta_q(a["tau"], a["dq"])
    over, rmse = _masked_metrics(pred, a["delta_q"], a["valid"])
    model.info.update({"n_samples": int(a["tau"].shape[0]), "over_estimation_fraction": dict(zip(names, over.tolist())),
                       "rmse": dict(zip(names, rmse.tolist())), "per_joint": dict(zip(names, extra))})
    return model


def _pwl_design(t, v, b1, b2, with_steps: bool) -> np.ndarray:
    cols = [np.ones_like(t), t, np.minimum(0.0, t - b1), np.maximum(0.0, t - b2), v]
    if with_steps:
        cols += [-(t < b1).astype(float), -(t > b2).astype(float)]
    return np.column_stack(cols)


def _bounded_fit(X: np.ndarray, y: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Least squares with coefficient 1 (the central slope) in [lo, hi]."""
    th = _scaled_lstsq(X, y)
    if lo <= th[1] <= hi:
        return th
    bound = lo if th[1] < lo else hi
    keep = [i for i in range(X.shape[1]) if i != 1]
    rest = _scaled_lstsq(X[:, keep], y - bound * X[:, 1])
    th = np.insert(rest, 1, bound)
    return th


def _pwl_one(t, v, y, lo, hi, max_iter, tol, where):
    q = np.quantile(t, [0.02, 1 / 3, 2 / 3, 0.98])
    span = max(q[3] - q[0], 1e-12)
    gap = 0.02 * span
    b1, b2 = q[1], q[2]
    conv = False
    it = 0
    for it in range(1, max_iter + 1):
        X = _pwl_design(t, v, b1, b2, True)
        if min((t < b1).sum(), ((t >= b1) & (t <= b2)).sum(), (t > b2).sum()) < 5:
            break
        th = _bounded_fit(X, y, lo, hi)
        s_mid, dl, dr, g1, g2 = th[1], th[2], th[3], th[5], th[6]
        st1 = g1 / dl if abs(dl) > 1e-12 * max(abs(s_mid), 1e-300) else 0.0
        st2 = g2 / dr if abs(dr) > 1e-12 * max(abs(s_mid), 1e-300) else 0.0
        st1 = float(np.clip(st1, -0.25 * span, 0.25 * span))
        st2 = float(np.clip(st2, -0.25 * span, 0.25 * span))
        nb1 = float(np.clip(b1 + st1, q[0], q[3] - gap))
        nb2 = float(np.clip(b2 + st2, nb1 + gap, q[3]))
        moved = max(abs(nb1 - b1), abs(nb2 - b2))
        b1, b2 = nb1, nb2
        if moved < tol * span:
            conv = True
            break
    X = _pwl_design(t, v, b1, b2, False)
    th = _bounded_fit(X, y, lo, hi)
    if not np.all(np.isfinite(th)):
        raise SolverError(f"{where}: piecewise-linear fit produced non-finite parameters")
    c, s_mid, dl, dr, kv = th
    return ({"c": c, "s_mid": s_mid, "s_left": s_mid + dl, "s_right": s_mid + dr, "b1": b1, "b2": b2, "k_v": kv},
            it, conv)

"""Joint friction: noise-aware Coulomb smoothing, the fitted low-speed transition and the
Stribeck velocity search.

Friction model of joint j (linear terms are regressor columns, see
:mod:`sensorless.regressor.terms`):

    τ_f = fs tanh(v/w) − (fs − fc)(1 − e^{−(v/vs)²}) sgn v + fv v + o,

rising from 0 to fs over the transition width w, decaying to fc over vs.

**Noise, rest and smoothing (the defaults).** The noise of a signal x is the
high-frequency part of it, the residual of a Savitzky–Golay fit, r = x − S x. For white
noise of std σ, var r = σ² (1 − c₀) with c₀ the centre coefficient of the smoother, so
σ̂ = 1.4826 · MAD(r) / √(1 − c₀) (robust to the motion's own residual at reversals).
A low-pass filter colours the noise (the estimate above would miss it): the noise is then
measured on the unfiltered logs (``noise_logs``) and σ_v scaled by √(B/(f_s/2)), B the
noise bandwidth ∫|H(f)|⁴ df of the zero-phase Butterworth filter at ``lowpass_hz``
(:func:`lowpass_noise_gain`).

A robot at rest has v = noise n, and a sliding-friction model fs sgn(n) chatters by fs,
far above the torque noise on a geared arm (fs of several N·m against σ_τ ~ 0.05 N·m).
Smoothing alone cannot fix it without blurring the friction in motion (chatter ≈ fs σ_v / ε
needs ε ≳ 2 fs σ_v / σ_τ, tens of σ_v, wider than a Stribeck bump). So, by default, rest is
found in preprocessing (:mod:`sensorless.data.rest`: |v| within 5 σ_v over the derivative
window → v = v̇ = 0, so sgn v = 0), and here

* **Coulomb smoothing** ε = ``factor`` σ_v (3): tanh(v/ε) only averages the sign over the
  velocity noise in motion. This is the simpler law's width w = ε. With ``width_grid="auto"``
  the width is also fitted: candidates log-spaced from ε/10 (a sharp sign whose noisy samples
  sit near zero at reversals) to 0.1 · P95|v| (friction that rises smoothly over a speed range,
  as measured below ~0.03 rad/s on geared arms) are compressed in the same pass, and a fitted
  width replaces ε only where it lowers the noise-normalised residual by more than ln N
  (BIC, :mod:`~.stribeck`; :func:`transition_grid`);
* optionally a per-sample **rest gate** δ (``rest_velocity``: "auto" = ``REST_SIGMAS`` σ_v of
  the unfiltered logs; default 0 = off): |v| ≤ δ gives no Coulomb/Stribeck friction and is
  left out of the fit (:class:`~sensorless.regressor.ModelStructure`). Per sample it cannot
  tell rest from a slow motion (it costs accuracy at reversals); the windowed test can.

:func:`coulomb_smoothing_from_noise` with ``sigma_tau``/``static_friction`` is the rule for
a model without a rest gate (``rest_velocity=0``): ε = max(k σ_v, 2 fs σ_v / σ_τ),
at most ``max_fraction`` · P95(|v|), so that the chatter at rest stays below σ_τ / 2.

**Stribeck velocity.** vs enters nonlinearly. Per joint a log-spaced grid of candidates
(:func:`stribeck_grid`) is compressed with the model in one pass, and the (w, vs) pair minimising the
weighted least-squares residual of the whole model is chosen by variable projection on the
compressed equations, or no Stribeck term where the log shows no physical effect
(:mod:`~.stribeck`); the model is then solved with those columns.
:func:`search_stribeck_velocity` is the same 1-D criterion on one joint's friction residual
r_j = τ_j − [Y π]_j − Ia_j v̇_j (for a friction-only log or a plot).
"""

from __future__ import annotations

import dataclasses
from typing import Iterable, Sequence

import numpy as np

from ..data.rest import signal_noise
from ..data.trajectory import Trajectory
from ..errors import DataError
from ..regressor.joint_terms import TermInputs, joint_term
from ..regressor.terms import ModelStructure, in_robot_order

__all__ = [
    "FrictionFit",
    "coulomb_smoothing_from_noise",
    "moving_joints",
    "friction_curve",
    "friction_residual",
    "lowpass_noise_gain",
    "REST_SIGMAS",
    "search_stribeck_velocity",
    "stribeck_grid",
    "transition_grid",
]

#: relative grid of Stribeck velocities (× P95 |v| of the joint)
STRIBECK_GRID = np.geomspace(0.005, 0.2, 25)
#: the grid's speed scale is at least this fraction of the joint's velocity limit (when the model has one):
#: a log that barely moves a joint (joint-wise logs, the first of which sets the grid) must not shrink it
GRID_SPEED_FLOOR = 0.1
#: rest velocity δ = REST_SIGMAS · σ_v (module docstring)
REST_SIGMAS = 5.0
#: the Stribeck bump must be wider than the Coulomb smoothing (vs ≥ this × ε): a narrower
#: one would only fit the sign chatter of a joint at rest
MIN_STRIBECK_OVER_SMOOTHING = 3.0
#: fitted transition widths: this many candidates, log-spaced from ε / WIDTH_GRID_BELOW to
#: WIDTH_GRID_TOP × the joint's speed scale (the simpler law's ε is always a candidate)
WIDTH_GRID_SIZE = 12
WIDTH_GRID_BELOW = 10.0
WIDTH_GRID_TOP = 0.1


def lowpass_noise_gain(cutoff_hz: float, rate_hz: float, order: int = 4) -> float:
    """Std ratio of white noise after the zero-phase Butterworth low-pass of
    :func:`sensorless.data.filtering.butter_lowpass` (``sosfiltfilt``: |H|² applied twice)."""
    from scipy.signal import butter, sosfreqz

    if not (cutoff_hz < rate_hz / 2):
        return 1.0
    sos = butter(int(order), cutoff_hz, btype="low", fs=rate_hz, output="sos")
    _, h = sosfreqz(sos, worN=8192, fs=rate_hz)
    return float(np.sqrt(np.mean(np.abs(h) ** 4)))


def _pooled_noise(arrays: Sequence[np.ndarray], moving: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Noise std pooled over logs (sample-count weighted variance); with ``moving`` (per log, a bool
    per column) each column pools only the logs where it moves (:func:`_moving_weights`)."""
    keep = [k for k, a in enumerate(arrays) if len(a) > 30]
    if not keep:
        raise DataError("no log is long enough (> 30 samples) to estimate the noise")
    sig = np.array([signal_noise(arrays[k]) for k in keep])
    w = _moving_weights([len(arrays[k]) for k in keep], None if moving is None else [moving[k] for k in keep])
    return np.sqrt(np.sum(w * sig**2, axis=0) / np.sum(w, axis=0))


def _moving_weights(lengths: Sequence[int], moving: Sequence[np.ndarray] | None) -> np.ndarray:
    """(logs, joints) weights: a log's sample count where the joint moves in it (every log for a
    joint that moves in none). A joint held still in a log has v ≡ 0 there: its 'noise' would pull
    the Coulomb smoothing ε of that joint to 0 (six single-joint calibration logs gave ε ~ 1e-56)."""
    n = np.asarray(lengths, dtype=float)[:, None]
    if moving is None:
        return n
    m = np.asarray(moving, dtype=bool)
    m[:, ~m.any(axis=0)] = True
    return n * m


def moving_joints(structure: ModelStructure, traj: Trajectory) -> np.ndarray:
    """Per term joint (actuated, then passive): does it move in this log (position range ≥ 1e-3)?"""
    t, cols = _act_columns(structure, traj)
    q = np.asarray(t.q)[:, cols]
    return np.ptp(q, axis=0) >= 1e-3 if len(q) else np.zeros(len(cols), dtype=bool)


def coulomb_smoothing_from_noise(
    sigma_v: np.ndarray, *, sigma_tau: np.ndarray | None = None, static_friction: np.ndarray | None = None,
    speed: np.ndarray | None = None, factor: float = 3.0, max_fraction: float = 0.1, margin: float = 2.0,
) -> np.ndarray:
    """ε per joint: ``max(factor σ_v, margin |fs| σ_v / σ_τ)``, at most ``max_fraction`` of the joint
    speed ``speed`` (P95 |v|) when given (module docstring)."""
    sigma_v = np.asarray(sigma_v, dtype=float)
    eps = factor * sigma_v
    if sigma_tau is not None and static_friction is not None:
        st = np.maximum(np.asarray(sigma_tau, dtype=float), 1e-12)
        eps = np.maximum(eps, margin * np.abs(np.asarray(static_friction, dtype=float)) * sigma_v / st)
    if speed is not None:
        eps = np.minimum(eps, max_fraction * np.asarray(speed, dtype=float))
    return np.where(np.isfinite(eps) & (eps > 0), eps, 0.0)


def _act_columns(structure: ModelStructure, traj: Trajectory) -> tuple[Trajectory, list[int]]:
    r = structure.robot
    traj = in_robot_order(r, traj)
    return traj, [r.joint_names.index(j) for j in r.term_joints]


def _friction_params(structure: ModelStructure, params: np.ndarray) -> np.ndarray:
    """``params`` with everything but the velocity-dependent friction terms and offset zeroed (the joint
    terms not on v̇)."""
    p = np.zeros_like(params)
    for j in structure.robot.term_joints:
        for t in structure.terms_of(j):
            if not joint_term(t).acceleration:
                k = structure.joint_term_index(j, t)
                p[k] = params[k]
    return p


def friction_residual(structure: ModelStructure, params: np.ndarray, traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """(v, r) per term joint (actuated, then passive), shape (N, n): r = τ − (rigid body + armature)
    prediction, the torque the friction model has to explain (τ = 0 on a passive joint)."""
    traj, cols = _act_columns(structure, traj)
    rigid = params - _friction_params(structure, params)
    pred = structure.torques(rigid, traj)[:, structure.term_rows]
    meas = structure.target(traj)[:, structure.term_rows]
    return traj.v[:, cols], meas - pred


def friction_curve(structure: ModelStructure, params: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Identified friction τ_f(v) per term joint (actuated, then passive) for velocities ``v`` (N, n)."""
    v = np.atleast_2d(np.asarray(v, dtype=float))
    V = np.zeros((v.shape[0], structure.robot.nv))
    V[:, structure.robot.term_v_indices] = v
    Z = np.sign(v) if any(joint_term(t).stateful for t in structure.joint_terms) else None  # steady sliding: sgn v
    F = structure.joint_features(V, np.zeros_like(V), Z)  # armature column 0 at zero acceleration
    nt, n = len(structure.joint_terms), len(structure.robot.term_joints)
    phi = _friction_params(structure, params)[structure.n_body_params:].reshape(n, nt) if nt else np.zeros((n, 0))
    return np.einsum("nkt,kt->nk", F, phi)


def search_stribeck_velocity(
    v: np.ndarray, r: np.ndarray, *, eps: float, terms: Sequence[str], grid: Sequence[float],
) -> tuple[float, np.ndarray]:
    """The vs in ``grid`` whose least-squares fit of r on the joint's friction columns
    ([v, T, T − (1 − exp(−(v/vs)²)) sgn v, 1] with T = tanh(v/ε), those in ``terms``) leaves the
    smallest residual; returns (vs, residual sum of squares per grid point)."""
    v, r = np.asarray(v, dtype=float), np.asarray(r, dtype=float)
    ok = np.isfinite(v) & np.isfinite(r)
    v, r = v[ok], r[ok]

    def columns(vs: float, names) -> list:  # the registry's columns of one joint (no rest gate)
        x = TermInputs(v[:, None], np.zeros((v.size, 1)), np.array([eps]), np.zeros(1), np.array([vs]))
        return [joint_term(t).column(x)[:, 0] for t in names]

    fixed = columns(1.0, [t for t in ("fv", "fc", "offset") if t in terms])
    sse = np.full(len(grid), np.inf)
    for i, vs in enumerate(grid):
        X = np.column_stack(fixed + columns(vs, ["stribeck"]))
        coef, *_ = np.linalg.lstsq(X, r, rcond=None)
        sse[i] = float(np.sum((r - X @ coef) ** 2))
    return float(grid[int(np.argmin(sse))]), sse


@dataclasses.dataclass
class FrictionFit:
    """How the friction settings were chosen (recorded in ``result.settings["friction"]``)."""

    coulomb_smoothing: dict[str, float]
    coulomb_smoothing_mode: str
    velocity_noise: dict[str, float] | None = None
    torque_noise: dict[str, float] | None = None
    stribeck_velocity: dict[str, float] | None = None
    stribeck_search: dict | None = None
    stribeck_grid: dict[str, list[float]] | None = None
    rest_velocity: dict[str, float] | None = None
    rest_velocity_mode: str = "off"
    #: candidate transition widths per joint (besides ε) and the fitted ones (None: the simpler law, w = ε)
    width_grid: dict[str, list[float]] | None = None
    transition_width: dict[str, "float | None"] | None = None

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def record_search(fit: FrictionFit, result) -> FrictionFit:
    """``fit`` completed with what the search of ``result`` chose (vs, fitted widths, the record)."""
    search = result.diagnostics.get("stribeck_search") or {}
    if fit.stribeck_grid:
        fit.stribeck_velocity = dict(result.structure.stribeck_velocity or {})
    fit.stribeck_search = search or None
    if fit.width_grid:
        fit.transition_width = {j: search.get(j, {}).get("width") for j in fit.width_grid}
    return fit


def friction_structure(
    structure: ModelStructure,
    logs: Iterable[Trajectory],
    *,
    coulomb_smoothing: "str | float" = "auto",
    stribeck_velocity: "str | float | dict" = "auto",
    factor: float = 3.0,
    noise_logs: Iterable[Trajectory] | None = None,
    lowpass_hz: float | None = None,
    width_grid: "str | dict | None" = "auto",
):
    """The structure :func:`~.friction_search.identify_friction` would fit, with ε set from ``logs`` and, when vs is
    "auto", the candidate grid in ``FrictionFit.stribeck_grid`` (the structure's vs is 0.1 · P95|v|
    until a fit chooses) and the candidate widths in ``FrictionFit.width_grid``: for fitting
    elsewhere, e.g. on Dask workers from ε and the grids measured on the client's log. Returns
    ``(structure, FrictionFit)``."""
    s, fit, _ = friction_setup(structure, list(logs), coulomb_smoothing, stribeck_velocity, 0.0, factor,
                                noise_logs, lowpass_hz, width_grid)
    return s, fit


def friction_setup(structure, train, coulomb_smoothing, stribeck_velocity, rest_velocity, factor, noise_logs,
                   lowpass_hz, width_grid="auto"):
    """``(structure with ε and the rest gate set, FrictionFit, whether vs is searched)`` from the
    training logs (arguments as :func:`~.friction_search.identify_friction`)."""
    joints = list(structure.robot.term_joints)
    has_stribeck = [j for j in joints if "stribeck" in structure.terms_of(j)]
    for name, val in (("coulomb_smoothing", coulomb_smoothing), ("rest_velocity", rest_velocity)):
        if isinstance(val, str) and val != "auto":
            raise DataError(f"{name} must be 'auto' or a number >= 0, got {val!r}")
    auto_eps, auto_rest = isinstance(coulomb_smoothing, str), isinstance(rest_velocity, str)
    auto_vs = isinstance(stribeck_velocity, str) and bool(has_stribeck)
    if isinstance(width_grid, str) and width_grid != "auto":
        raise DataError(f"width_grid must be 'auto', candidate widths per joint or None, got {width_grid!r}")
    auto_w = width_grid == "auto" and auto_eps and structure.friction_law == "blend"
    speed, sigma_v = None, None
    if auto_eps or auto_rest or auto_vs:
        v_all = [_act_columns(structure, t)[0].v[:, _act_columns(structure, t)[1]] for t in train]
        w = _moving_weights([len(v) for v in v_all], [moving_joints(structure, t) for t in train]) > 0
        speed = np.array([np.percentile(np.abs(np.concatenate([v[:, k] for v, use in zip(v_all, w[:, k]) if use])), 95)
                          for k in range(len(joints))])  # per joint, over the logs where it moves
        speed = np.where(speed > 0, speed, 1.0)
    if auto_eps or auto_rest:
        raw = list(noise_logs) if noise_logs is not None else train
        moving = [moving_joints(structure, t) for t in raw]
        sigma_v = _logged_velocity_noise(structure, raw, moving)
        if sigma_v is None:
            sigma_v = _pooled_noise([_act_columns(structure, t)[0].v[:, _act_columns(structure, t)[1]] for t in raw],
                                    moving)
        sigma_raw = sigma_v
        if lowpass_hz:
            sigma_v = sigma_v * lowpass_noise_gain(lowpass_hz, float(np.median([t.rate for t in train])))
    if auto_eps:
        eps = coulomb_smoothing_from_noise(sigma_v, speed=speed, factor=factor)
    elif isinstance(coulomb_smoothing, dict):  # per joint, e.g. measured on another log
        eps = np.array([float(coulomb_smoothing[j]) for j in joints])
    else:
        eps = np.full(len(joints), float(coulomb_smoothing))
    rest = (coulomb_smoothing_from_noise(sigma_raw, speed=speed, factor=REST_SIGMAS) if auto_rest
            else np.full(len(joints), float(rest_velocity)))
    grid = None
    limits = dict(zip(structure.robot.joint_names, structure.robot.velocity_limits()))
    vlim = np.array([limits.get(j, np.inf) for j in joints])
    law = [j for j in joints if any(joint_term(t).reversal for t in structure.terms_of(j))]
    if auto_w:
        width_grid = transition_grid(speed, eps, joints, law, vlim)
    elif isinstance(width_grid, str):
        width_grid = None
    low = np.array([min([eps[k]] + (width_grid or {}).get(j, [])) for k, j in enumerate(joints)])
    if isinstance(stribeck_velocity, str):
        if stribeck_velocity != "auto":
            raise DataError(f"stribeck_velocity must be 'auto' or a number > 0, got {stribeck_velocity!r}")
        vs = {j: float(0.1 * speed[k]) for k, j in enumerate(joints) if j in has_stribeck} if has_stribeck else None
        grid = stribeck_grid(speed, low, rest, joints, has_stribeck, vlim) if has_stribeck else None
    elif isinstance(stribeck_velocity, dict) and any(np.ndim(x) for x in stribeck_velocity.values()):
        grid = {j: list(map(float, np.atleast_1d(x))) for j, x in stribeck_velocity.items()}  # candidates given
        vs = {j: g[len(g) // 2] for j, g in grid.items()}
        auto_vs = bool(grid)
    elif isinstance(stribeck_velocity, dict):
        vs = dict(stribeck_velocity)
    else:
        vs = {j: float(stribeck_velocity) for j in has_stribeck} or None

    s = dataclasses.replace(structure, coulomb_smoothing=dict(zip(joints, map(float, eps))),
                            stribeck_velocity=vs, per_joint_terms=_per_joint_terms(structure),
                            rest_velocity={j: float(d) for j, d in zip(joints, rest) if d > 0} or None)
    fit = FrictionFit(coulomb_smoothing=dict(zip(joints, map(float, eps))),
                      coulomb_smoothing_mode="auto" if auto_eps else "given", stribeck_velocity=vs, stribeck_grid=grid,
                      rest_velocity=dict(zip(joints, map(float, rest))),
                      rest_velocity_mode="auto" if auto_rest else ("given" if np.any(rest > 0) else "off"),
                      width_grid=width_grid or None)
    if sigma_v is not None:
        fit.velocity_noise = dict(zip(joints, map(float, sigma_v)))
        fit.torque_noise = dict(zip(joints, map(float, _pooled_noise([s.target(t)[:, s.actuated_rows] for t in raw]))))
    return s, fit, auto_vs


def stribeck_grid(speed: np.ndarray, eps: np.ndarray, rest: np.ndarray, joints: Sequence[str],
                  has_stribeck: Sequence[str], velocity_limit: np.ndarray | None = None) -> dict[str, list[float]]:
    """Candidate vs per joint: :data:`STRIBECK_GRID` × s, s = max(P95|v|, :data:`GRID_SPEED_FLOOR` ×
    the velocity limit when finite), at least :data:`MIN_STRIBECK_OVER_SMOOTHING` × max(ε, δ) (the
    largest point if none is)."""
    if velocity_limit is not None:
        lim = np.asarray(velocity_limit, dtype=float)
        speed = np.maximum(speed, np.where(np.isfinite(lim) & (lim > 0), GRID_SPEED_FLOOR * lim, 0.0))
    out = {}
    for k, j in enumerate(joints):
        if j not in has_stribeck:
            continue
        grid = STRIBECK_GRID * speed[k]
        lo = MIN_STRIBECK_OVER_SMOOTHING * max(eps[k], rest[k])
        out[j] = (grid[grid >= lo] if np.any(grid >= lo) else grid[-1:]).tolist()
    return out


def transition_grid(speed: np.ndarray, eps: np.ndarray, joints: Sequence[str], law_joints: Sequence[str],
                    velocity_limit: np.ndarray | None = None) -> dict[str, list[float]]:
    """Candidate transition widths per joint with an fc or stribeck term (module docstring):
    :data:`WIDTH_GRID_SIZE` values log-spaced from ε / :data:`WIDTH_GRID_BELOW` to
    :data:`WIDTH_GRID_TOP` × s (s as in :func:`stribeck_grid`); none for a joint with ε = 0."""
    if velocity_limit is not None:
        lim = np.asarray(velocity_limit, dtype=float)
        speed = np.maximum(speed, np.where(np.isfinite(lim) & (lim > 0), GRID_SPEED_FLOOR * lim, 0.0))
    out = {}
    for k, j in enumerate(joints):
        lo, hi = eps[k] / WIDTH_GRID_BELOW, WIDTH_GRID_TOP * speed[k]
        if j in law_joints and 0 < lo < hi:
            out[j] = np.geomspace(lo, hi, WIDTH_GRID_SIZE).tolist()
    return out


def _logged_velocity_noise(structure: ModelStructure, logs: list, moving: list | None = None) -> "np.ndarray | None":
    """σ_v per actuated joint measured by the rest detection of every log (its v is 0 at rest
    afterwards, which would bias a new estimate low), pooled over the logs where the joint moves
    (:func:`_moving_weights`); None if a log has none."""
    infos = [t.provenance.get("rest") for t in logs]
    if not infos or any(i is None for i in infos):
        return None
    joints = structure.robot.term_joints
    try:
        sig = np.array([[i["velocity_noise"][j] for j in joints] for i in infos], dtype=float)
    except KeyError:
        return None
    w = _moving_weights([len(t) for t in logs], moving)
    return np.sqrt(np.sum(w * sig**2, axis=0) / np.sum(w, axis=0))


def _per_joint_terms(structure: ModelStructure):
    return None if getattr(structure, "per_joint_terms", None) is None else dict(structure.per_joint_terms)

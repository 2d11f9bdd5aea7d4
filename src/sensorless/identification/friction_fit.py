"""Choosing and fitting one joint's friction law from bench logs: a static law, or a state.

Data: per log the joint's position q, velocity v, acceleration v̇ (for an ``inertia`` term) and
torque τ at its own time stamps (no uniform sampling needed). Every candidate is linear in its
amplitudes given its non-linear parameters (:mod:`sensorless.regressor.friction_state`), so each is a least-squares
fit of τ, and the non-linear ones are chosen on grids (variable projection):

* **static**: τ_f = fc tanh(v/ε) [+ (fs − fc) e^{−(v/vs)²} tanh(v/ε)] + fv v + o [+ J v̇], ε on a
  geometric grid from the velocity noise (:func:`~.friction.coulomb_smoothing_from_noise`) up to
  :data:`WIDTH_SPAN` × the 95th percentile of |v| (a given ``coulomb_smoothing`` fixes it), vs on the
  grid of :func:`~.friction.stribeck_grid`;
* **state**: the Dahl/LuGre states s_c, s_s for each inverse presliding distance k on a grid
  (1/k from 10⁻⁴ to 0.3 × the median stroke between reversals, strokes within :data:`STROKE_PLAYS`
  play half-widths left out, and at least twice the play
  half-width h = 3 position-noise stds, at least one encoder step), each vs, with or without the damping σ1 (q̇ − |q̇| s_c),
  plus one initial-state column e^{−kS} per log.

**Drives.** A series with a drive input u (a motor current, or an input torque) has the output
torque τ_out as its torque: the fit is of K u = τ_out + τ_f, i.e. of −τ_out on the law's columns and
−u (the gain K, always), with two optional terms (:mod:`sensorless.regressor.friction_state`):
``gain_back`` (the gain differs when the output drives the motor back), ``load`` (Coulomb friction
growing with |τ_out|) and, where the motor-side position is logged, ``stiffness`` (an elastic
transmission: the pair ``stiffness_motor``, ``stiffness_out``). The Coulomb term is then optional too (``terms`` without ``fc``: the linear
current fit K u + o).

**Choice.** Each candidate is scored by BIC = N ln(SSE/N) + p ln N (p: its amplitudes, initial states
and non-linear parameters) and, with ``choice="held-out"`` (the bench command's), by its **blocked
held-out error**: the data are cut into folds (each log one fold when there are several logs, else
:data:`TIME_FOLDS` contiguous time blocks; blocks as long as a log are far longer than the residual's
correlation), each fold is predicted by the amplitudes fitted on the others (one Gram matrix per fold:
no refit of the columns) and the squared errors are summed. Within a structure (its set of terms, static
or state) the non-linear parameters ε, vs and k are those that fit best (lowest SSE: variable
projection); the structure, i.e. the optional terms and the state, is the one with the lowest held-out
error (an extra term has to lower it to be kept); ``choice="bic"`` takes the lowest BIC instead. A Stribeck term counts only with fs − fc > 0 (as
in :mod:`.stribeck`), a load term only with μ > 0, a state only with fc > 0, σ1 ≥ 0 and a presliding
distance above the grid's shortest (a state that wants an even shorter one is the static law).
Intervals (95 %) of the amplitudes are from the Newey–West covariance (the residuals of a friction fit
are correlated over many samples), widened to the spread of the fold estimates (a block jackknife with
Student's t on folds − 1 degrees of freedom, three folds or more) where that is wider; that of 1/k
from the BIC-scaled profile of the residual over the k grid.

**Signs.** A Coulomb friction, a gain or a load coefficient whose whole interval is below 0 is refused
(:class:`~sensorless.errors.DataError`) with its likely cause (which signal's sign is reversed) and the
option that reverses it (:func:`sign_diagnosis`).
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from ..data.rest import signal_noise
from ..data.trajectory import Trajectory
from ..errors import DataError, ExcitationError, OptionError, setting
from .friction import coulomb_smoothing_from_noise, stribeck_grid
from ..regressor.friction_state import LAW_TERMS, STATE_BLOCK, FrictionLaw, dahl_state_blocks, dahl_states, play

__all__ = ["CHOICES", "DEFAULT_TERMS", "FIT_TERMS", "STATE_MODES", "TIME_FOLDS", "JointFit", "JointSeries",
           "encoder_quantum", "fit_joint_friction", "joint_series", "sign_diagnosis"]

#: terms fitted by default (``damping`` is offered with a state; ``stribeck``, the drive terms
#: ``gain_back`` and ``load`` (with a drive) and the state are kept where the choice supports them)
DEFAULT_TERMS = ("fc", "stribeck", "fv", "offset", "inertia", "gain_back", "load", "stiffness")
#: every term a bench fit takes (``gain`` is implied by a drive input; ``stiffness`` is the pair
#: ``stiffness_motor``, ``stiffness_out``)
FIT_TERMS = ("fc", "stribeck", "damping", "fv", "offset", "inertia", "gain_back", "load", "stiffness")
STATE_MODES = ("auto", "on", "off")
#: how candidates are compared (module docstring)
CHOICES = ("held-out", "bic")
#: folds of a single log (contiguous time blocks)
TIME_FOLDS = 5
#: presliding distances 1/k, × the median stroke between reversals
PRESLIDING_GRID = np.geomspace(1e-4, 0.3, 25)
#: dissipative or inertial terms kept ≥ 0 (a negative slope at low speed is the Stribeck term's)
NONNEGATIVE = ("damping", "fv", "inertia")
#: the Coulomb transition widths tried: from the noise-based ε up to this × the 95th percentile of |v|
WIDTH_SPAN = 0.2
#: ... on this many points (geometric), then refined this many times (9 points between the best's neighbours)
WIDTH_POINTS = 8
WIDTH_REFINE = 2
#: strokes shorter than this many play half-widths are left out of the median stroke (dither at a turn)
STROKE_PLAYS = 4.0
#: play half-width h = this × the position noise std
PLAY_SIGMAS = 3.0
_Z95 = 1.959964


@dataclasses.dataclass
class JointSeries:
    """One joint of one log: 1-D arrays at the log's own stamps; with a ``drive`` input u (current or
    input torque), ``tau`` is the output torque τ_out (module docstring); ``motor`` the motor-side
    position."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    a: "np.ndarray | None" = None
    source: str = "<array>"
    drive: "np.ndarray | None" = None
    motor: "np.ndarray | None" = None

    def __len__(self) -> int:
        return int(self.t.size)


def joint_series(traj: Trajectory, joint: str) -> JointSeries:
    """Joint ``joint`` of ``traj`` (it must have v and τ). A log with an output torque
    (``extras["tau_out"]``) gives a drive series: u = its current (``extras["current"]``), else its τ."""
    if joint not in traj.joint_names:
        raise DataError(f"no joint '{joint}' in the log (joints: {list(traj.joint_names)})", traj.source)
    j = list(traj.joint_names).index(joint)
    out, cur = traj.extras.get("tau_out"), traj.extras.get("current")
    drive = None
    if out is not None:
        drive = cur if cur is not None else traj.tau
        if drive is None or np.ndim(drive) != 2:
            raise DataError(f"the output torque of '{joint}' is logged but no drive input: map the motor current "
                            f"({setting('columns', {'current': '...'})}) or the input torque", traj.source)
        drive = np.asarray(drive, dtype=float)[:, j]
        tau = np.asarray(out, dtype=float)[:, j]
    elif traj.tau is None:
        raise DataError(f"the friction fit needs the velocity and the torque of '{joint}'", traj.source)
    else:
        tau = traj.tau[:, j]
    if traj.v is None:
        raise DataError(f"the friction fit needs the velocity and the torque of '{joint}'", traj.source)
    qm = traj.extras.get("q_motor")
    return JointSeries(traj.t, traj.q[:, j], traj.v[:, j], tau, None if traj.a is None else traj.a[:, j],
                       traj.source, drive, None if qm is None or drive is None else np.asarray(qm, dtype=float)[:, j])


@dataclasses.dataclass
class JointFit:
    """The chosen law of a joint, the best static law, and how they were chosen (``held_out``: the
    blocked held-out SSE of the best candidate of each kind, module docstring)."""

    joint: str
    law: FrictionLaw
    static: FrictionLaw
    bic: dict
    reason: str
    intervals: dict
    presliding_interval: "list[float] | None"
    profile: dict
    n_samples: int
    noise: dict
    held_out: "dict | None" = None

    def to_dict(self) -> dict:
        return {"law": self.law.to_dict(), "static": self.static.to_dict(), "bic": self.bic, "reason": self.reason,
                "intervals": self.intervals, "presliding_interval": self.presliding_interval,
                "presliding_profile": self.profile, "n_samples": self.n_samples, "noise": self.noise,
                "held_out": self.held_out}


@dataclasses.dataclass
class _Candidate:
    kind: str
    terms: tuple
    vs: float
    k: float
    coef: np.ndarray
    sse: float
    n_params: int
    ok: bool
    bic: float = np.inf
    cv: float = np.inf
    folds: "np.ndarray | None" = None
    eps: float = 0.0
    source: "tuple | None" = None  # (Gram, column positions, non-negative positions)

    def summary(self) -> dict:
        return {"kind": self.kind, "terms": list(self.terms), "vs": self.vs or None,
                "coulomb_smoothing": self.eps if self.kind == "static" else None,
                "presliding_distance": 1.0 / self.k if self.k else None, "bic": float(self.bic),
                "held_out_sse": float(self.cv) if np.isfinite(self.cv) else None, "valid": bool(self.ok)}


def _lstsq(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Equilibrated least squares from normal equations (a column without rows gets 0)."""
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    return np.linalg.lstsq(G / np.outer(d, d), b / d, rcond=1e-12)[0] / d


class _Gram:
    """Normal equations of a column set M (N, c) against y, to fit any subset of its columns,
    accumulated over blocks of rows (:meth:`add`), one set per fold (``folds``; :meth:`held_out`)."""

    def __init__(self, c: int, folds: int = 1) -> None:
        self.Gf, self.bf, self.yyf = np.zeros((folds, c, c)), np.zeros((folds, c)), np.zeros(folds)

    @property
    def G(self) -> np.ndarray:
        return self.Gf.sum(axis=0)

    @property
    def b(self) -> np.ndarray:
        return self.bf.sum(axis=0)

    @property
    def yy(self) -> float:
        return float(self.yyf.sum())

    def add(self, M: np.ndarray, y: np.ndarray, fold: "int | np.ndarray" = 0) -> "_Gram":
        """Rows ``M``, ``y`` of fold ``fold`` (one fold, or one per row)."""
        if np.ndim(fold) == 0:
            self.Gf[fold] += M.T @ M
            self.bf[fold] += M.T @ y
            self.yyf[fold] += float(y @ y)
            return self
        for f in np.unique(fold):
            r = fold == f
            self.add(M[r], y[r], int(f))
        return self

    def fit(self, idx: Sequence[int], nonneg: Sequence[int] = ()) -> tuple[np.ndarray, float, int]:
        """(coefficients, SSE, columns used) of the columns ``idx`` (equilibrated least squares), the
        coefficients at positions ``nonneg`` kept ≥ 0: a negative one is fixed at 0 (its column
        dropped, the most negative first) and the rest refitted."""
        c, free = _bounded_fit(self.G, self.b, idx, nonneg)
        G, b = self.G[np.ix_(idx, idx)], self.b[idx]
        return c, float(max(self.yy - 2 * c @ b + c @ G @ c, 0.0)), int(free.sum())

    def held_out(self, idx: Sequence[int], nonneg: Sequence[int] = ()) -> tuple[float, np.ndarray]:
        """(Σ over folds of the fold's SSE with the amplitudes fitted on the other folds, those
        amplitudes (folds, len(idx))); inf with one fold."""
        nf = self.Gf.shape[0]
        if nf < 2:
            return np.inf, np.zeros((0, len(idx)))
        idx = np.asarray(idx, dtype=int)
        G, b = self.G, self.b
        sse, coefs = 0.0, []
        for f in range(nf):
            if self.yyf[f] == 0.0 and not self.Gf[f].any():
                continue
            # a column (a log's initial state) with next to nothing outside the fold gets 0, not a wild value
            Gt = G - self.Gf[f]
            seen = np.diag(Gt)[idx] > _SEEN * np.maximum(np.diag(G)[idx], 1e-300)
            c, _ = _bounded_fit(Gt, b - self.bf[f], idx, nonneg, seen)
            Gh, bh = self.Gf[f][np.ix_(idx, idx)], self.bf[f][idx]
            sse += max(float(self.yyf[f] - 2 * c @ bh + c @ Gh @ c), 0.0)
            coefs.append(c)
        return sse, np.array(coefs)


#: a column whose squared norm outside a held-out fold is below this share of its total is not fitted there
_SEEN = 1e-6


def _bounded_fit(G: np.ndarray, b: np.ndarray, idx, nonneg, seen=None) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of columns ``idx`` from normal equations ``G``, ``b``, those at positions ``nonneg``
    held ≥ 0 (:meth:`_Gram.fit`) and those not ``seen`` (a mask) held at 0, and the mask of the free ones."""
    idx = np.asarray(idx, dtype=int)
    free = np.ones(idx.size, dtype=bool) if seen is None else np.asarray(seen, dtype=bool).copy()
    nonneg = np.asarray(list(nonneg), dtype=int)
    while True:
        sub = idx[free]
        c = np.zeros(idx.size)
        c[free] = _lstsq(G[np.ix_(sub, sub)], b[sub])
        bad = [i for i in nonneg if free[i] and c[i] < 0]
        if not bad:
            return c, free
        free[min(bad, key=lambda i: c[i])] = False


def sign_diagnosis(coef: dict, intervals: dict, *, drive: bool) -> "str | None":
    """The likely cause of a Coulomb friction, gain or load coefficient whose 95 % interval lies below 0,
    and the option that fixes it (None when every sign is plausible). With a drive, K u = τ_out + τ_f:
    K < 0 with fc < 0 is a reversed output torque, K < 0 alone a reversed current (drive input), fc < 0
    alone a reversed position; without one, fc < 0 is a torque or position sign reversed."""
    def neg(t):
        iv = intervals.get(t)
        return t in coef and iv is not None and iv[1] < 0

    fc, gain = neg("fc"), neg("gain")
    flip = lambda what: f"rerun with {setting('flip', what)}"  # noqa: E731
    if drive and gain and fc:
        return (f"the gain K = {coef['gain']:.4g} and the Coulomb friction fc = {coef['fc']:.4g} are both negative: "
                f"the output torque's sign is reversed (its sensor counts the other way); {flip('tau_out')}")
    if drive and gain:
        return (f"the gain K = {coef['gain']:.4g} is negative while the friction opposes the motion: the drive "
                f"input's sign (current or input torque) is reversed; {flip('current')}")
    if fc:
        what = "the gain and the friction" if drive else "the torque"
        return (f"the Coulomb friction fc = {coef['fc']:.4g} is negative (friction pushing along the motion): the "
                f"position and velocity count the other way from {what}; {flip('q')}"
                + ("" if drive else f" (or {setting('flip', 'tau')})"))
    if neg("load"):
        return (f"the load coefficient μ = {coef['load']:.4g} is negative (friction falling with the load): the "
                "output torque is likely not the transmitted torque (wrong channel or scale); leave 'load' out of "
                f"{setting('terms')}")
    return None


def _turning_strokes(qp: np.ndarray) -> np.ndarray:
    """Distances travelled between consecutive reversals of a (played) position."""
    dq = np.diff(qp)
    idx = np.flatnonzero(dq != 0)
    if idx.size < 2:
        return np.zeros(0)
    s = np.sign(dq[idx])
    turns = idx[np.flatnonzero(s[1:] != s[:-1]) + 1]
    pts = np.concatenate([[0], turns, [qp.size - 1]])
    return np.abs(np.diff(qp[pts]))[1:-1] if turns.size >= 2 else np.zeros(0)


def _lagged_products(Z: np.ndarray, starts: Sequence[int], max_lag: int) -> np.ndarray:
    """C[l] = Σ_i Z[i + l]ᵀ Z[i] (p, p) for l = 0 … max_lag, with i and i + l in the same log (FFT)."""
    n, p = Z.shape
    ends = list(starts[1:]) + [n]
    out = np.zeros((max_lag + 1, p, p))
    for s, t in zip(starts, ends):
        F = np.fft.rfft(Z[s:t], n=2 * (t - s), axis=0)
        for i in range(p):  # one column at a time: memory O(N p), not O(N p²)
            c = np.fft.irfft(F[:, i, None] * np.conj(F), n=2 * (t - s), axis=0)[: max_lag + 1]
            out[: c.shape[0], i, :] += c
    return out


def _hac(X: np.ndarray, e: np.ndarray, starts: Sequence[int]) -> tuple[np.ndarray, float]:
    """Newey–West covariance of least-squares coefficients (Bartlett weights; the lag is twice the
    one where the residual autocorrelation falls below 0.05, at most N/4; lags within a log only)
    and the long-run inflation 1 + 2 Σ w_l ρ_l of the residual variance."""
    n = e.size
    r = (e - e.mean())[:, None]
    rho = _lagged_products(r, starts, max(min(n // 4, 2000), 1))[:, 0, 0]
    rho = rho / max(rho[0], 1e-300)
    below = np.flatnonzero(rho < 0.05)
    lag = int(min(2 * (below[0] if below.size else rho.size), n // 4, 4000))
    w = 1.0 - np.arange(1, lag + 1) / (lag + 1)
    C = _lagged_products(X * e[:, None], starts, lag)
    S = C[0] + np.einsum("l,lij->ij", w, C[1:] + C[1:].transpose(0, 2, 1))
    rho = _lagged_products(r, starts, lag)[:, 0, 0] / max(float(r[:, 0] @ r[:, 0]), 1e-300)
    infl = 1.0 + 2.0 * float(w @ rho[1:])
    Ginv = np.linalg.pinv(X.T @ X)
    return Ginv @ S @ Ginv, max(infl, 1.0)


def _score_held_out(c: "_Candidate") -> "_Candidate":
    """``c`` with its blocked held-out SSE and per-fold amplitudes (:meth:`_Gram.held_out`), computed once."""
    if c.folds is None:
        gram, idx, nonneg = c.source
        c.cv, c.folds = gram.held_out(idx, nonneg)
    return c


def _check_log_signs(chosen: "_Candidate", series: Sequence[JointSeries], joint: str) -> None:
    """DataError when the logs, each fitted alone with the terms of ``chosen`` (the plain law), give the
    gain (a drive) or the Coulomb friction (a plain bench) clearly opposite signs (one log's sensor counts the other way: a flip for every log cannot
    fix it)."""
    gram, idx, nonneg = chosen.source
    own = np.array([_bounded_fit(gram.Gf[f], gram.bf[f], idx, nonneg)[0] for f in range(len(series))])
    # the gain of a drive (its friction can be small beside K u), else the Coulomb friction
    for t in (("gain",) if "gain" in chosen.terms else ("fc",)):
        if t not in chosen.terms:
            continue
        x = own[:, chosen.terms.index(t)]
        scale = float(np.median(np.abs(x)))
        pos, neg = x > 0.25 * scale, x < -0.25 * scale
        if pos.any() and neg.any():
            minority = neg if neg.sum() <= pos.sum() else pos
            names = ", ".join(f"{series[i].source} ({x[i]:.4g})" for i in np.flatnonzero(minority))
            raise DataError(f"joint '{joint}': fitted alone, the logs give {t} opposite signs ({names} against "
                            f"{np.median(x[~minority]):.4g} in the others): a sensor of those logs counts the other "
                            f"way; {setting('flip')} reverses every log, so fit them separately with it")


def encoder_quantum(dq: np.ndarray) -> float:
    """The step of a quantized position (its smallest non-zero change, when 95 % of the changes are whole
    multiples of it), else 0."""
    dq = np.abs(np.asarray(dq, dtype=float))
    dq = dq[dq > 0]
    if dq.size < 10:
        return 0.0
    step = float(dq.min())
    m = dq / step
    return step if np.mean(np.abs(m - np.round(m)) < 0.01) >= 0.95 else 0.0


def _folds(series: Sequence[JointSeries]) -> tuple[list[np.ndarray], int]:
    """Per series the fold of each row, and the number of folds: one per log, or :data:`TIME_FOLDS`
    contiguous blocks of a single log."""
    if len(series) >= 2:
        return [np.full(len(s), i) for i, s in enumerate(series)], len(series)
    n = len(series[0])
    return [np.minimum(np.arange(n) * TIME_FOLDS // max(n, 1), TIME_FOLDS - 1)], TIME_FOLDS


def fit_joint_friction(series: Sequence[JointSeries], *, joint: str = "joint", terms: Sequence[str] = DEFAULT_TERMS,
                       state: str = "auto", coulomb_smoothing: "str | float" = "auto",
                       choice: str = "bic") -> JointFit:
    """Fit one joint's friction on its logs ``series`` and choose static or state (module docstring).
    ``terms``: among :data:`FIT_TERMS` (fc is required without a drive input; ``gain_back`` and ``load``
    apply with one); ``state``: "auto" (by ``choice``), "on" (the best state law) or "off";
    ``choice``: "held-out" (blocked held-out error) or "bic"."""
    terms = tuple(terms)
    series = [s for s in series if len(s)]
    drive = bool(series) and all(s.drive is not None for s in series)
    if series and not drive and any(s.drive is not None for s in series):
        raise DataError(f"joint '{joint}': some logs have an output torque and a drive input and some do not; "
                        "fit them separately")
    bad = [t for t in terms if t not in FIT_TERMS]
    if bad or ("fc" not in terms and not drive):
        raise OptionError(f"friction terms of '{joint}' must include fc and be among {', '.join(FIT_TERMS)}; "
                          f"got {list(terms)}")
    if state not in STATE_MODES:
        raise OptionError(f"{setting('state')} must be one of {', '.join(STATE_MODES)}, got {state!r}")
    if choice not in CHOICES:
        raise OptionError(f"the choice must be one of {', '.join(CHOICES)}, got {choice!r}")
    if not series or sum(len(s) for s in series) < 50:
        raise DataError(f"joint '{joint}': fewer than 50 samples to fit friction on")
    for s in series:
        arrays = ([("t", s.t), ("q", s.q), ("v", s.v), ("tau", s.tau)] + ([("v̇", s.a)] if "inertia" in terms else [])
                  + ([("drive input", s.drive)] if drive else []))
        for name, x in arrays:
            if x is None:
                raise DataError(f"joint '{joint}': the inertia term needs the acceleration v̇ (no log has it)", s.source)
            bad_i = np.flatnonzero(~np.isfinite(x))
            if bad_i.size:
                raise DataError(f"joint '{joint}': {name} is not finite at sample {int(bad_i[0])}", s.source)
    with_fc = "fc" in terms
    opt_load = drive and "load" in terms
    opt_back = drive and "gain_back" in terms
    opt_stiff = drive and "stiffness" in terms and all(s.motor is not None for s in series)
    # with a drive the law's sum is τ_f − K u = −τ_out (:mod:`sensorless.regressor.friction_state`)
    y = np.concatenate([-s.tau if drive else s.tau for s in series])
    v_all = np.concatenate([s.v for s in series])
    N = y.size
    speed = float(np.percentile(np.abs(v_all), 95))
    if not speed > 0:
        raise ExcitationError(f"joint '{joint}' does not move in the logs: its friction cannot be identified")
    long = [s for s in series if len(s) > 30]
    sig_v = float(np.median([signal_noise(s.v)[0] for s in long])) if long else 0.0
    sig_q = float(np.median([signal_noise(s.q)[0] for s in long])) if long else 0.0
    dt = float(np.median(np.concatenate([np.diff(s.t) for s in series])))
    eps = (float(coulomb_smoothing_from_noise(np.array([sig_v]), speed=np.array([speed]))[0])
           if coulomb_smoothing == "auto" else float(coulomb_smoothing))
    quantum = encoder_quantum(np.concatenate([np.diff(s.q) for s in series]))
    # a play of one encoder count at least: a count flickering back and forth is not a reversal
    h = max(PLAY_SIGMAS * max(sig_q, sig_v * dt), quantum)
    grid_vs = (stribeck_grid(np.array([speed]), np.array([eps]), np.array([0.0]), [joint], [joint])[joint]
               if "stribeck" in terms and with_fc else [])
    starts = np.cumsum([0] + [len(s) for s in series[:-1]]).tolist()
    fold_rows, n_folds = _folds(series)
    fold = np.concatenate(fold_rows)
    qps = [play(s.q, h) for s in series]
    strokes = np.concatenate([_turning_strokes(qp) for qp in qps])
    strokes = strokes[strokes > STROKE_PLAYS * h]  # back-and-forth within a few plays is dither, not a stroke
    # the transition width ε of tanh(v/ε): from the velocity noise up (a compliant drive's friction turns
    # over a wider band than the noise), chosen with vs per structure (variable projection)
    widths = (np.unique(np.geomspace(eps, max(eps, WIDTH_SPAN * speed), WIDTH_POINTS)) if coulomb_smoothing == "auto"
              and eps > 0 else np.array([eps]))
    noise = {"velocity": sig_v, "position": sig_q, "coulomb_smoothing": eps, "play": h, "encoder_step": quantum,
             "median_stroke": float(np.median(strokes)) if strokes.size else None, "reversals": int(strokes.size)}

    u_all = np.concatenate([s.drive for s in series]) if drive else None
    fixed = {"fv": v_all, "offset": np.ones(N),
             "inertia": np.concatenate([s.a for s in series]) if "inertia" in terms else None,
             "gain": None if u_all is None else -u_all,
             "stiffness_motor": -np.concatenate([s.motor for s in series]) if opt_stiff else None,
             "stiffness_out": -np.concatenate([s.q for s in series])}
    base_terms = [t for t in ("fv", "offset", "inertia") if t in terms] + (["gain"] if drive else []) + (
        ["stiffness_motor", "stiffness_out"] if opt_stiff else [])
    B = np.column_stack([fixed[t] for t in base_terms]) if base_terms else np.zeros((N, 0))
    load_abs = np.abs(np.concatenate([s.tau for s in series])) if opt_load else np.zeros(N)
    back_u = u_all if opt_back else np.zeros(N)
    bic_of = lambda sse, p: N * np.log(max(sse, 1e-300) / N) + p * np.log(N)  # noqa: E731
    cands: list[_Candidate] = []

    def add(gram, idx, kind, names, vs=0.0, k=0.0, extra=0, width=0.0) -> _Candidate:
        nonneg = [i for i, t in enumerate(names) if t in NONNEGATIVE]
        c, sse, used = gram.fit(idx, nonneg)
        ok = all(c[names.index(t)] > 0 for t in ("fc", "stribeck", "load")
                 if t in names and (kind == "state" or t != "fc"))
        p = used + extra
        cand = _Candidate(kind, tuple(names), vs, k, c, sse, p, bool(ok), bic_of(sse, p), eps=width,
                          source=(gram, idx, nonneg))
        cands.append(cand)
        return cand

    groups = ([("gain_back",)] if opt_back else []) + ([("stiffness_motor", "stiffness_out")] if opt_stiff else []) + (
        [("load",)] if opt_load else [])
    optional = {t for g in groups for t in g}
    combos = [tuple(t for g, on in zip(groups, mask) for t in g if on)
              for mask in np.ndindex(*(2,) * len(groups))] if groups else [()]

    def structures(pos: dict, core: list) -> list:
        """(column positions, names) in law-term order for the ``core`` names plus each combination of
        the optional groups (gain_back; the stiffness pair; load); ``pos``: name -> column."""
        out = []
        for extra_terms in combos:
            names = sorted(core + [t for t in base_terms if t not in optional] + list(extra_terms), key=LAW_TERMS.index)
            out.append(([pos[t] for t in names], names))
        return out

    def sc_columns(sc: np.ndarray, rows: slice) -> np.ndarray:
        """The columns that depend on the Coulomb sign or state s_c: gain_back, load (:mod:`..friction_state`)."""
        u = back_u[rows]
        return np.column_stack([-u * np.maximum(0.0, -np.sign(u) * sc), load_abs[rows] * sc])

    nb, m = B.shape[1], len(grid_vs)
    pos = {"fc": 0, **{t: 1 + m + i for i, t in enumerate(base_terms)}, "gain_back": 1 + m + nb, "load": 2 + m + nb}

    def static_pass(ws) -> None:
        for width in ws:
            sgn = np.tanh(v_all / width) if width > 0 else np.sign(v_all)
            gram = _Gram(1 + m + nb + 2, n_folds)
            for i0 in range(0, N, STATE_BLOCK):
                sl = slice(i0, min(i0 + STATE_BLOCK, N))
                gram.add(np.column_stack([sgn[sl]] + [np.exp(-((v_all[sl] / vs) ** 2)) * sgn[sl] for vs in grid_vs]
                                         + [B[sl], sc_columns(sgn[sl], sl)]), y[sl], fold[sl])
            for j, vs in enumerate([None] + list(grid_vs)):
                core = (["fc"] if with_fc else []) + (["stribeck"] if vs else [])
                for idx, names in structures({**pos, "stribeck": j}, core):
                    add(gram, idx, "static", names, vs or 0.0, extra=(1 if vs else 0) + (len(widths) > 1),
                        width=width)

    static_pass(widths)
    tried = widths
    for _ in range(WIDTH_REFINE if widths.size > 1 else 0):  # refine ε between the best point's neighbours
        top = min((c for c in cands if c.kind == "static" and c.ok), key=lambda c: c.bic)
        g = int(np.argmin(np.abs(tried - top.eps)))
        fine = np.geomspace(tried[max(g - 1, 0)], tried[min(g + 1, tried.size - 1)], 9)
        static_pass([w for w in fine if not np.any(np.isclose(w, tried))])
        tried = np.unique(np.concatenate([tried, fine]))
    key = (lambda c: (c.cv, c.n_params)) if choice == "held-out" else (lambda c: (c.bic, c.n_params))

    def best(kind: str) -> "_Candidate | None":
        """The structure (terms) of ``kind`` with the best score, each structure with its best-fitting
        non-linear parameters (vs, k: lowest BIC = SSE, variable projection)."""
        per: dict = {}
        for c in cands:
            if c.kind == kind and c.ok and (c.terms not in per or c.bic < per[c.terms].bic):
                per[c.terms] = c
        for c in per.values():  # the held-out error only of each structure's best fit (the costly part)
            _score_held_out(c)
        return min(per.values(), key=key) if per else None

    static_best = best("static")
    score = lambda c: c.cv if choice == "held-out" else c.bic  # noqa: E731
    label = "held-out SSE" if choice == "held-out" else "BIC"

    why_not = None
    lengths = noise["median_stroke"] * PRESLIDING_GRID if strokes.size else np.zeros(0)
    lengths = lengths[lengths >= 2 * h]
    if state == "off":
        why_not = f"state off ({setting('state', 'off')})"
    elif not with_fc:
        why_not = "no Coulomb term: no state"
    elif strokes.size < 2:
        why_not = "fewer than two strokes between reversals: presliding cannot be seen"
    elif lengths.size < 3:
        why_not = "the position noise hides every presliding distance shorter than 0.3 × the stroke"
    else:
        k_grid = 1.0 / lengths
        ctx = (series, qps, starts, B, y, base_terms, fold_rows, n_folds, sc_columns, structures)
        _state_candidates(ctx, k_grid, list(grid_vs), (False, True), add)
        sharp = float(k_grid.max()) * (1 - 1e-12)
        for c in cands:
            if c.kind == "state" and c.k >= sharp:
                c.ok = False  # sharper than the grid resolves: that is the static law
        top = best("state")
        if top is not None:  # refine k around the best grid point for its vs and damping choice
            g = int(np.argmin(np.abs(k_grid - top.k)))
            fine = np.geomspace(k_grid[max(g - 1, 0)], k_grid[min(g + 1, k_grid.size - 1)], 17)
            _state_candidates(ctx, fine[fine < sharp], [top.vs] if top.vs else [], ("damping" in top.terms,), add,
                              with_none=not top.vs)
    state_best = best("state")
    if why_not is None and state_best is None:
        why_not = "no state law with fc > 0 and a presliding distance longer than the grid's shortest"
    profile = {}
    if state_best is not None:
        same = sorted((c for c in cands if c.kind == "state" and c.terms == state_best.terms
                       and c.vs == state_best.vs), key=lambda c: -c.k)
        profile = {"presliding_distance": [1.0 / c.k for c in same], "bic": [float(c.bic) for c in same]}
    if state == "on" and state_best is None:
        raise ExcitationError(f"joint '{joint}': {setting('state', 'on')}, but {why_not}")
    if state_best is not None and (state == "on" or score(state_best) < score(static_best)):
        chosen = state_best
        reason = ("state (chosen: on)" if state == "on" else
                  f"state: {label} {score(state_best):.4g} below the static law's {score(static_best):.4g}")
    else:
        chosen = static_best
        reason = why_not or (f"static: the state law's {label} {score(state_best):.4g} is not below the static "
                             f"law's {score(static_best):.4g}")
    law, static_law = _law(chosen, h), _law(static_best, h)
    intervals, infl = _intervals(chosen, series, qps, starts, y)
    plain = [c for c in cands if c.kind == "static" and not set(c.terms) & (optional | {"stribeck"})]
    base = _score_held_out(min(plain, key=lambda c: c.bic)) if plain else chosen
    # signs are read on the plain law: optional terms (a stiffness) can leave the gain undetermined
    wrong = sign_diagnosis(dict(zip(base.terms, base.coef)), _intervals(base, series, qps, starts, y)[0]
                           if base is not chosen else intervals, drive=drive)
    if wrong is not None:
        raise DataError(f"joint '{joint}': {wrong}", series[0].source)
    if len(series) >= 2:
        _check_log_signs(base, series, joint)
    pre = None
    if chosen.kind == "state":
        # N ln(SSE/SSE_min) ≈ ΔSSE/σ² ≤ χ²₁(95 %) × the long-run inflation of the residual variance
        pre = _profile_interval(np.array(profile["presliding_distance"]), np.array(profile["bic"]), 3.84 * infl)
    best_of = {}
    for c in cands:
        k2 = (c.kind, "stribeck" in c.terms, "damping" in c.terms, "gain_back" in c.terms, "load" in c.terms,
              "stiffness_out" in c.terms)
        if c.ok and (k2 not in best_of or c.bic < best_of[k2].bic):
            best_of[k2] = c
    bic = {"static": float(static_best.bic), "state": None if state_best is None else float(state_best.bic),
           "chosen": chosen.kind, "choice": choice,
           "candidates": [c.summary() for c in sorted(best_of.values(), key=key)]}
    held = None
    if np.isfinite(static_best.cv):
        held = {"folds": int(n_folds), "by": "log" if len(series) >= 2 else "time block",
                "static": float(static_best.cv) / N,
                "state": None if state_best is None or not np.isfinite(state_best.cv) else float(state_best.cv) / N,
                "chosen": float(chosen.cv) / N if np.isfinite(chosen.cv) else None}
    return JointFit(joint, law, static_law, bic, reason, intervals, pre, profile, int(N), noise, held)


def _intervals(c: "_Candidate", series, qps, starts, y: np.ndarray) -> tuple[dict, float]:
    """95 % intervals of candidate ``c``'s amplitudes (module docstring: Newey–West, widened to the block
    jackknife with Student's t) and the long-run inflation of the residual variance."""
    X = _design(c, series, qps, starts)
    e = y - X @ c.coef
    free = np.array([not (i < len(c.terms) and c.terms[i] in NONNEGATIVE and c.coef[i] == 0.0)
                     for i in range(X.shape[1])])
    cov, infl = _hac(X[:, free], e, starts)
    sd = np.zeros(X.shape[1])
    sd[free] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    half = _Z95 * sd
    if c.folds is not None and c.folds.shape[0] >= 3:
        # block jackknife over the folds: the spread of the estimate across independent parts of the data,
        # with F − 1 degrees of freedom (Student's t: three blocks say little about a spread)
        from scipy.special import stdtrit  # Student's t quantile (scipy.stats loads in seconds)

        F = c.folds.shape[0]
        jk = np.sqrt((F - 1) / F * np.sum((c.folds - c.folds.mean(axis=0)) ** 2, axis=0))
        half[: jk.size] = np.maximum(half[: jk.size], float(stdtrit(F - 1, 0.975)) * jk)
    # a term held at its bound 0 (its unconstrained value was negative) has no interval (None)
    return ({t: [float(c.coef[i] - half[i]), float(c.coef[i] + half[i])] if free[i] else None
             for i, t in enumerate(c.terms)}, infl)


def _profile_interval(L: np.ndarray, b: np.ndarray, level: float) -> list[float]:
    """Where the profile b(L) stays within ``level`` of its minimum: the grid points, widened by the
    parabola in ln L through the minimum and its neighbours (the grid is coarser than the interval)."""
    x, order = np.log(L), np.argsort(L)
    x, b = x[order], b[order]
    keep = np.concatenate([[True], np.diff(x) > 1e-9])
    x, b = x[keep], b[keep]
    i = int(np.argmin(b))
    lo, hi = x[b - b[i] <= level].min(), x[b - b[i] <= level].max()
    if 0 < i < x.size - 1:
        c2 = np.polyfit(x[i - 1:i + 2], b[i - 1:i + 2], 2)
        if c2[0] > 0:
            x0 = -c2[1] / (2 * c2[0])
            half = np.sqrt(level / c2[0])
            lo, hi = min(lo, x0 - half), max(hi, x0 + half)
    return [float(np.exp(lo)), float(np.exp(hi))]


def _initial_columns(qps, starts, k: float) -> np.ndarray:
    """(N, n_logs): e^{−k S} on each log's rows (S the distance travelled since its start)."""
    N = starts[-1] + qps[-1].size
    out = np.zeros((N, len(qps)))
    for i, (s0, qp) in enumerate(zip(starts, qps)):
        out[s0:s0 + qp.size, i] = np.exp(-k * np.concatenate([[0.0], np.cumsum(np.abs(np.diff(qp)))]))
    return out


def _state_candidates(ctx, k_grid, vs_list, damping, add, with_none: bool = True) -> None:
    """Add, via ``add``, the state candidates for each k of ``k_grid``, each vs of ``vs_list`` (and no
    Stribeck term with ``with_none``), with each ``damping`` choice and each combination of the optional
    drive terms. The columns of each k are [s_c, s_s (each vs), damping, fixed terms, gain_back, load,
    initial states], folded into one Gram matrix per k and fold block by block
    (:func:`~sensorless.regressor.friction_state.dahl_state_blocks`: memory independent of the log length)."""
    series, qps, starts, B, y, base_terms, fold_rows, n_folds, sc_columns, structures = ctx
    if len(k_grid) == 0:
        return
    k_grid = np.asarray(k_grid, dtype=float)
    m, nb, n_logs = len(vs_list), B.shape[1], len(series)
    grams = [_Gram(2 + m + nb + 2 + n_logs, n_folds) for _ in k_grid]
    for i, (qp, ser, s0) in enumerate(zip(qps, series, starts)):
        travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(qp)))])
        for i0, i1, S in dahl_state_blocks(qp, ser.v, k_grid, vs_list):
            rows = slice(s0 + i0, s0 + i1)
            v, Bb, yb = ser.v[i0:i1], B[rows], y[rows]
            fb = fold_rows[i][i0:i1]
            init = np.zeros((i1 - i0, n_logs))
            for g, k in enumerate(k_grid):
                init[:, i] = np.exp(-k * travel[i0:i1])
                sc = S[:, g, 0]
                grams[g].add(np.column_stack([S[:, g, :], v - np.abs(v) * sc, Bb, sc_columns(sc, rows), init]), yb, fb)
    rest = list(range(4 + m + nb, 4 + m + nb + n_logs))
    pos = {"fc": 0, "damping": 1 + m, **{t: 2 + m + i for i, t in enumerate(base_terms)}, "gain_back": 2 + m + nb,
           "load": 3 + m + nb}
    for g, k in enumerate(k_grid):
        for j, vs in ([(None, None)] if with_none else []) + list(enumerate(vs_list)):
            for d in damping:
                core = ["fc"] + (["stribeck"] if vs else []) + (["damping"] if d else [])
                for idx, names in structures({**pos, "stribeck": 1 + (j or 0)}, core):
                    add(grams[g], idx + rest, "state", names, vs or 0.0, float(k), extra=1 + (1 if vs else 0))


def _law(c: _Candidate, h: float) -> FrictionLaw:
    coef = dict(zip(c.terms, map(float, c.coef[: len(c.terms)])))
    if c.kind == "state":
        return FrictionLaw("state", coef, vs=c.vs, k=c.k, play=h)
    return FrictionLaw("static", coef, eps=c.eps, vs=c.vs)


def _design(c: _Candidate, series, qps, starts) -> np.ndarray:
    """The regressor of candidate ``c`` (a state's with its initial-state columns)."""
    law = _law(c, 0.0)
    if c.kind == "static":
        return np.concatenate([law.columns(s.q, s.v, s.a, drive=s.drive, load=s.tau, motor=s.motor) for s in series])
    X = np.concatenate([law.columns(s.q, s.v, s.a, states=dahl_states(qp, s.v, [c.k], [c.vs or 1.0])[:, 0, :],
                                    drive=s.drive, load=s.tau, motor=s.motor)
                        for qp, s in zip(qps, series)])
    return np.column_stack([X, _initial_columns(qps, starts, c.k)])

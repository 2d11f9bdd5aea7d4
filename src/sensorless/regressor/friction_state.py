"""Joint friction with a state: presliding and frictional memory (Dahl/LuGre type).

A velocity-only law τ_f(v) jumps at a reversal and has one value per velocity. Real joints show
*presliding* (after a reversal the friction ramps over a small displacement while the joint
barely moves) and *hysteresis* (the friction lags the velocity). LuGre (Canudas de Wit et al.
1995) models both with a bristle deflection z: ż = v − σ0 |v| z / g(v), g(v) = fc + (fs − fc)
e^{−(v/vs)²}, τ_f = σ0 z + σ1 ż + σ2 v. Its relaxation length g/σ0 makes τ_f non-linear in all
parameters. Here the relaxation length is one constant 1/k [rad or m] (the presliding distance,
k = σ0/fc), which makes the state equation linear:

    ds_c/dq = k (sgn q̇ − s_c),      ds_s/dq = k (e^{−(q̇/vs)²} sgn q̇ − s_s),   (dq = |dq| sgn q̇)

    τ_f = fc s_c + (fs − fc) s_s + σ1 (q̇ − |q̇| s_c) + fv q̇ + o  (+ J q̈ on a bench),

so σ0 z = fc s_c + (fs − fc) s_s (LuGre with g/σ0 → 1/k) and σ1 ż = σ1 (q̇ − |q̇| s_c). Given k
(and vs) the torque is **linear** in (fc, fs − fc, σ1, fv, o, J): k is chosen by variable projection
on a grid, as the Stribeck velocity is (:mod:`sensorless.identification.friction_fit`). The states depend on the path,
not on time (rate-independent): with the input u held over a step (its sign that of the step),
the exact update from sample i−1 to i is

    s_i = u_i + (s_{i−1} − u_i) e^{−k |Δq_i|},   u_i = [1, e^{−(v̄_i/vs)²}] sgn Δq_i,  v̄_i = (v_{i−1} + v_i)/2,

which needs no uniform sampling (an irregular or missing step only changes Δq). Position noise
at rest would make the state random-walk towards 0; q is therefore first passed through a
*play operator* of half-width h (a few position-noise stds, :func:`play`): it moves only when q
leaves ±h around it, so noise does not move the state and a motion shifts it by h ≪ 1/k. From an
initial state s(0) the solution is the one from 0 plus s(0) e^{−k S_i} (S the travelled distance):
a fit gives each log a column e^{−kS} (its unknown initial state); a prediction starts at 0.
As k → ∞ the states become sgn q̇ (the static law); :mod:`sensorless.identification.friction_fit` keeps the state only
where the data support a finite presliding distance.

The static law (``kind="static"``) is the one of :mod:`sensorless.regressor.terms`:
τ_f = fc tanh(v/ε) + (fs − fc) e^{−(v/vs)²} tanh(v/ε) + fv v + o (+ J v̇).

**Drives** (a bench that logs the drive input u, a motor current or an input torque, *and* the output
torque τ_out; :mod:`sensorless.identification.friction_fit`): the input drives the output through the
friction, K u = τ_out + τ_f, with the gain K among the amplitudes. Three terms of a law say so:

* ``gain`` K, column −u (the law's sum is τ_f − K u = −τ_out);
* ``gain_back`` ΔK, column −u·w, w = max(0, −sgn(u) s_c) (max(0, −sgn(u) T) in a static law): the gain
  while the output drives the motor back (direction-dependent efficiency: K when driving, K + ΔK when
  back-driven; w is 0 at rest and 1 once sliding against u, with the Coulomb term's transition);
* ``load`` μ, column |τ_load| s_c (|τ_load| T in a static law): Coulomb friction that grows with the
  transmitted torque, (fc + μ |τ_load|) s;
* ``stiffness_motor``, ``stiffness_out`` (a pair, where the motor-side position q_m is logged too):
  columns −q_m and −q, so τ_out gains k_m q_m + k_o q: an elastic transmission (a cable, a strain-wave
  gear) whose twist r q_m − q carries torque (k_m = k r, k_o = −k; its rest twist is in the offset).

A prediction of τ_out without τ_load takes τ_load = τ_out and solves τ_out = r − μ |τ_out| s for it
(r the rest of K u − τ_f): τ_out = r / (1 + μ s sgn r), one value for |μ s| < 1
(:meth:`FrictionLaw.output_torque`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Iterator, Sequence

import numpy as np

from ..errors import DataError, ParameterError

__all__ = ["DRIVE_TERMS", "FrictionLaw", "FrictionStateIntegrator", "LAW_KINDS", "LAW_TERMS", "STATE_BLOCK", "dahl_state_blocks",
           "dahl_states", "play",
           "presliding_states"]

LAW_KINDS = ("static", "state")
#: linear terms of a law, in column order (``damping`` only with a state; ``inertia`` = J v̇)
LAW_TERMS = ("fc", "stribeck", "damping", "fv", "offset", "inertia", "gain", "gain_back", "load", "stiffness_motor",
             "stiffness_out")
#: terms of a drive (module docstring: u and τ_out logged)
DRIVE_TERMS = ("gain", "gain_back", "load", "stiffness_motor", "stiffness_out")


def play(q: np.ndarray, h: float, start: float | None = None) -> np.ndarray:
    """Play (backlash) operator of half-width ``h``: p_i = clip(p_{i−1}, q_i − h, q_i + h),
    p_0 = ``start`` (default q_0). Rate-independent; noise within ±h does not move it."""
    q = np.asarray(q, dtype=float)
    if h <= 0 or q.size == 0:
        return q.copy()
    out = np.empty_like(q)
    p = float(q[0] if start is None else start)
    lo, hi = q - h, q + h
    for i in range(q.size):
        p = min(max(p, lo[i]), hi[i])
        out[i] = p
    return out


#: rows per block of :func:`dahl_state_blocks` (memory: block × len(k) × (1 + len(vs)) floats)
STATE_BLOCK = 4096


def dahl_state_blocks(qp: np.ndarray, v: np.ndarray, k: np.ndarray, vs: Sequence[float] = (),
                      block: int = STATE_BLOCK) -> Iterator[tuple[int, int, np.ndarray]]:
    """The states of :func:`dahl_states` as blocks of rows ``(i0, i1, states[i0:i1])`` (the exact
    update of the module docstring, the state carried across blocks; a step with Δq = 0 leaves it)."""
    qp, v = np.asarray(qp, dtype=float), np.asarray(v, dtype=float)
    k = np.atleast_1d(np.asarray(k, dtype=float))
    vs = np.asarray(list(vs), dtype=float)
    n = qp.size
    dq = np.diff(qp, prepend=qp[:1])
    vbar = 0.5 * (v + np.concatenate([v[:1], v[:-1]]))
    s = np.zeros((k.size, 1 + vs.size))
    for i0 in range(0, n, max(int(block), 1)):
        i1 = min(i0 + int(block), n)
        U = np.concatenate([np.ones((i1 - i0, 1)), np.exp(-((vbar[i0:i1, None] / vs[None, :]) ** 2))], axis=1)
        U *= np.sign(dq[i0:i1])[:, None]
        A = np.exp(-np.abs(dq[i0:i1])[:, None] * k[None, :])[:, :, None]  # (n_b, G, 1)
        out = np.empty((i1 - i0, k.size, 1 + vs.size))
        last = 0
        for i in np.flatnonzero(dq[i0:i1]):
            out[last:i] = s
            s = U[i] + (s - U[i]) * A[i]
            last = i
        out[last:] = s
        yield i0, i1, out


def dahl_states(qp: np.ndarray, v: np.ndarray, k: np.ndarray, vs: Sequence[float] = ()) -> np.ndarray:
    """States along a log from 0 (module docstring): ``qp`` the played position (N,), ``v`` the
    velocity (N,), ``k`` the candidate inverse presliding distances (G,), ``vs`` Stribeck velocities
    (m). Returns (N, G, 1 + m): s_c, then s_s for each vs (:func:`dahl_state_blocks`)."""
    parts = [b for _, _, b in dahl_state_blocks(qp, v, k, vs)]
    k = np.atleast_1d(np.asarray(k, dtype=float))
    return np.concatenate(parts) if parts else np.zeros((0, k.size, 1 + len(list(vs))))


def presliding_states(q: np.ndarray, v: np.ndarray, laws: Sequence["dict | None"]) -> np.ndarray:
    """The Coulomb state s_c (N, n) of joints ``q``, ``v`` (N, n) along a log from 0: per column with a
    law ``{"k", "play"}`` :func:`dahl_states` with that k on the position played with half-width
    ``play`` (the ``presliding`` column of a rigid-body model); 0 where the law is None."""
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    Z = np.zeros(q.shape)
    for c, law in enumerate(laws):
        if law is not None:
            Z[:, c] = dahl_states(play(q[:, c], law["play"]), v[:, c], [law["k"]])[:, 0, 0]
    return Z


@dataclasses.dataclass
class FrictionLaw:
    """One joint's identified friction (module docstring). ``kind``: "static" or "state";
    ``coef``: {term: value} for the terms it has (:data:`LAW_TERMS`); ``eps`` the Coulomb smoothing
    of the static law; ``vs`` the Stribeck velocity (with a ``stribeck`` term); ``k`` [1/rad] the
    inverse presliding distance and ``play`` [rad] the play half-width of a state law."""

    kind: str
    coef: dict
    eps: float = 0.0
    vs: float = 0.0
    k: float = 0.0
    play: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in LAW_KINDS:
            raise ParameterError(f"friction law kind must be one of {LAW_KINDS}, got {self.kind!r}")
        bad = [t for t in self.coef if t not in LAW_TERMS or (t == "damping" and self.kind == "static")]
        if bad:
            raise ParameterError(f"unknown friction term(s) {bad} for a {self.kind} law; terms are {LAW_TERMS}")
        self.coef = {t: float(self.coef[t]) for t in LAW_TERMS if t in self.coef}
        for name in ("eps", "vs", "k", "play"):
            val = float(getattr(self, name))
            if not (math.isfinite(val) and val >= 0):
                raise ParameterError(f"friction law {name} must be a finite number >= 0, got {val!r}")
            setattr(self, name, val)
        if "stribeck" in self.coef and self.vs <= 0:
            raise ParameterError("a friction law with a Stribeck term needs vs > 0")
        if self.kind == "state" and self.k <= 0:
            raise ParameterError("a state friction law needs k > 0 (the inverse presliding distance)")

    @property
    def terms(self) -> tuple[str, ...]:
        return tuple(self.coef)

    @property
    def presliding_distance(self) -> float | None:
        """1/k [rad or m] of a state law (None for a static law)."""
        return 1.0 / self.k if self.kind == "state" else None

    @property
    def is_drive(self) -> bool:
        """Whether the law has a gain: it maps a drive input u to the output torque (module docstring)."""
        return "gain" in self.coef

    def columns(self, q: np.ndarray, v: np.ndarray, a: "np.ndarray | None" = None, *,
                states: "np.ndarray | None" = None, drive: "np.ndarray | None" = None,
                load: "np.ndarray | None" = None, motor: "np.ndarray | None" = None) -> np.ndarray:
        """Regressor (N, len(terms)) along a log from the zero state (``states``: precomputed
        (N, 2) [s_c, s_s] of this law, e.g. from :func:`dahl_states`; ``drive`` u, ``load`` τ_load and
        ``motor`` the motor-side position q_m for the drive terms, module docstring)."""
        v = np.asarray(v, dtype=float)
        if "inertia" in self.coef and a is None:
            raise DataError("the friction law has an inertia term and needs the acceleration v̇")
        if ("gain" in self.coef or "gain_back" in self.coef) and drive is None:
            raise DataError("the friction law has a drive gain and needs the drive input (current or input torque)")
        if "load" in self.coef and load is None:
            raise DataError("the friction law has a load-dependent term and needs the load torque")
        if "stiffness_motor" in self.coef and motor is None:
            raise DataError("the friction law has a transmission stiffness and needs the motor-side position q_motor")
        if self.kind == "state":
            if states is None:
                states = dahl_states(play(q, self.play), v, [self.k], [self.vs or 1.0])[:, 0, :]
            sc, ss = states[:, 0], states[:, 1]
        else:
            sc = np.tanh(v / self.eps) if self.eps > 0 else np.sign(v)
            ss = np.exp(-((v / (self.vs or 1.0)) ** 2)) * sc
        cols = {"fc": sc, "stribeck": ss, "damping": v - np.abs(v) * sc, "fv": v, "offset": np.ones_like(v),
                "inertia": None if a is None else np.asarray(a, dtype=float)}
        if drive is not None:
            u = np.asarray(drive, dtype=float)
            cols["gain"], cols["gain_back"] = -u, -u * np.maximum(0.0, -np.sign(u) * sc)
        if load is not None:
            cols["load"] = np.abs(np.asarray(load, dtype=float)) * sc
        if motor is not None:
            cols["stiffness_motor"] = -np.asarray(motor, dtype=float)
        cols["stiffness_out"] = -np.asarray(q, dtype=float)
        return np.column_stack([cols[t] for t in self.terms]) if self.terms else np.zeros((v.size, 0))

    def torque(self, q: np.ndarray, v: np.ndarray, a: "np.ndarray | None" = None, *,
               drive: "np.ndarray | None" = None, load: "np.ndarray | None" = None,
               motor: "np.ndarray | None" = None) -> np.ndarray:
        """τ_f (+ J v̇) along a log, the state starting at 0 (N,); a drive law's τ_f − K u = −τ_out."""
        return self.columns(q, v, a, drive=drive, load=load, motor=motor) @ np.array(list(self.coef.values()))

    def drive_torque(self, q: np.ndarray, v: np.ndarray, *, drive: np.ndarray,
                     motor: "np.ndarray | None" = None) -> np.ndarray:
        """The torque a drive law's drive terms deliver (K u + ΔK u w + k_m q_m + k_o q; N,): minus the
        output torque, the friction (0 for a law without drive terms)."""
        terms = [t for t in self.terms if t in ("gain", "gain_back", "stiffness_motor", "stiffness_out")]
        if not terms:
            return np.zeros(np.shape(v))
        cols = self.columns(q, v, np.zeros(np.shape(v)), drive=drive, load=np.zeros(np.shape(v)), motor=motor)
        return -cols[:, [self.terms.index(t) for t in terms]] @ np.array([self.coef[t] for t in terms])

    def output_torque(self, q: np.ndarray, v: np.ndarray, a: "np.ndarray | None" = None, *,
                      drive: np.ndarray, motor: "np.ndarray | None" = None) -> np.ndarray:
        """A drive law's output torque τ_out from the drive input u alone (N,): with a ``load`` term
        τ_load = τ_out, solved in closed form (module docstring)."""
        mu = self.coef.get("load", 0.0)
        rest = FrictionLaw(self.kind, {t: c for t, c in self.coef.items() if t != "load"}, self.eps, self.vs, self.k,
                           self.play)
        r = -rest.torque(q, v, a, drive=drive, motor=motor)
        if mu == 0.0:
            return r
        s = self.columns(q, v, None if "inertia" not in self.coef else a, drive=drive, motor=motor,
                         load=np.ones_like(np.asarray(v, dtype=float)))[:, self.terms.index("load")]
        return r / np.maximum(1.0 + mu * s * np.sign(r), 1e-6)

    def steady(self, v: np.ndarray) -> np.ndarray:
        """The friction in steady sliding at velocities ``v`` (states at their bounds; no inertia)."""
        v = np.asarray(v, dtype=float)
        sgn = np.tanh(v / self.eps) if self.kind == "static" and self.eps > 0 else np.sign(v)
        c = self.coef
        return (c.get("fc", 0.0) * sgn + c.get("stribeck", 0.0) * np.exp(-((v / (self.vs or 1.0)) ** 2)) * sgn
                + c.get("fv", 0.0) * v + c.get("offset", 0.0))

    def to_dict(self) -> dict:
        return {"kind": self.kind, "coef": dict(self.coef), "eps": self.eps, "vs": self.vs, "k": self.k,
                "play": self.play}

    @classmethod
    def from_dict(cls, d: dict) -> "FrictionLaw":
        return cls(d["kind"], dict(d["coef"]), d.get("eps", 0.0), d.get("vs", 0.0), d.get("k", 0.0),
                   d.get("play", 0.0))


class FrictionStateIntegrator:
    """The friction of laws ``laws`` (one per joint) one sample at a time, carrying the states:
    :meth:`step` (q, v[, v̇]) → τ_f (n,), the same numbers as :meth:`FrictionLaw.torque` on the log."""

    def __init__(self, laws: Sequence[FrictionLaw]) -> None:
        self.laws = list(laws)
        self.reset()

    def reset(self) -> None:
        """Forget the states: the next :meth:`step` starts them at 0."""
        n = len(self.laws)
        self._p = None
        self._v = np.zeros(n)
        self._s = np.zeros((n, 2))

    def step(self, q: np.ndarray, v: np.ndarray, a: "np.ndarray | None" = None) -> np.ndarray:
        q, v = np.asarray(q, dtype=float).ravel(), np.asarray(v, dtype=float).ravel()
        n = len(self.laws)
        if q.shape != (n,) or v.shape != (n,):
            raise DataError(f"the friction state needs {n} joint positions and velocities, got {q.shape} and {v.shape}")
        first = self._p is None
        if first:
            self._p = q.copy()
        out = np.zeros(n)
        for j, law in enumerate(self.laws):
            if law.kind == "state":
                if not first:
                    p = min(max(self._p[j], q[j] - law.play), q[j] + law.play)
                    dq = p - self._p[j]
                    self._p[j] = p
                    if dq != 0:
                        vbar = 0.5 * (v[j] + self._v[j])
                        u = np.array([1.0, math.exp(-((vbar / (law.vs or 1.0)) ** 2))]) * math.copysign(1.0, dq)
                        self._s[j] = u + (self._s[j] - u) * math.exp(-law.k * abs(dq))
                states = self._s[j][None, :]
            else:
                states = None
            aj = None if a is None else np.asarray(a, dtype=float).ravel()[j:j + 1]
            out[j] = (law.columns(q[j:j + 1], v[j:j + 1], aj, states=states) @ np.array(list(law.coef.values())))[0]
        self._v = v.copy()
        return out

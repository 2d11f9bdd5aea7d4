"""The momentum observer's step, compiled: one ctypes call per sample into the C++ kernel.

``observer_kernel.cpp`` (built with the regressor kernel by ``python -m sensorless.regressor.native_build``,
see :mod:`sensorless.regressor.native`) holds a copy of the identified model (the kinematic tree,
identified inertias, armature, gravity), the friction and drive terms, the presliding state, the
observer's filter state and the collision check, and computes one sample of
:meth:`~.momentum.MomentumObserver.step` (M, Cᵀv and g by Pinocchio's C++ algorithms) into
preallocated buffers. :func:`native_observer` describes a dynamics object with a ``kernel_spec()``
(a :class:`~.momentum.MomentumDynamics`) to the kernel and, given the Python ``reference`` observer,
accepts it only when its steps equal the reference's (relative 1e-9) on random states; otherwise, and when the kernel is not built or ``SENSORLESS_NATIVE=0``, it returns the
reason and the Python step is used.
"""

from __future__ import annotations

import ctypes
import functools
import weakref
from typing import Callable

import numpy as np

from ..errors import ShapeMismatchError
from ..regressor import native

__all__ = ["NativeObserver", "available", "native_observer", "random_states"]

#: per dynamics object, None (the kernel's steps equal Python's) or the reason they do not
_CHECKED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_DEFAULT_BASE = np.array([0, 0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0])


@functools.lru_cache(maxsize=None)
def _lib():
    lib = native.library()
    if lib is None or not hasattr(lib, "slo_step"):
        return None
    p, i, d = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
    lib.slo_new.restype = p
    lib.slo_new.argtypes = [p, i, p, p, p]
    lib.slo_free.argtypes = [p]
    lib.slo_set_joints.argtypes = [p, i, p, p, p, i, i, p]
    lib.slo_set_transmission.argtypes = [p, p, p, p, p]
    lib.slo_add_joint_friction.argtypes = [p, i, d, d, d, i, d, d, d, d]
    lib.slo_add_presliding.argtypes = [p, i, i, d, d, d]
    lib.slo_add_drive.argtypes = [p, p, d, d, d, d, d, d, d]
    lib.slo_set_filter.argtypes = [p, i, p, p, p]
    lib.slo_set_monitor.argtypes = [p, i, p, p, p, ctypes.c_long]
    lib.slo_reset.argtypes = [p]
    lib.slo_in_size.restype = i
    lib.slo_in_size.argtypes = [p]
    lib.slo_bind.argtypes = [p, p, p]
    lib.slo_step.restype = i
    lib.slo_step.argtypes = [p, i]
    lib.slo_run.restype = i
    lib.slo_run.argtypes = [p, i, p, i, p, p, p, p]
    lib.slo_tree_state.argtypes = [p, p, i, p, p]
    lib.slo_bare.argtypes = [p, i, p, p, p, p]
    return lib


def available() -> bool:
    """True when the kernel is built with the observer step and enabled."""
    return _lib() is not None


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


class NativeObserver:
    """The kernel's observer of one dynamics (build it with :func:`native_observer`).

    :meth:`step` copies one sample into the bound input buffer, runs the kernel and leaves
    r (n,) in :attr:`r` and τ_ext = −r[rows] (m,) in :attr:`tau_ext`; it returns the contact
    flag (False until :meth:`set_monitor`). Nothing is allocated per call."""

    def __init__(self, lib, handle: int, n: int, nj: int, na: int, floating: bool, nq: int, nv: int):
        self._lib, self._h = lib, handle
        self._nq, self._nv = nq, nv
        self.n, self.nj, self.na, self.floating = n, nj, na, floating
        self.in_size = lib.slo_in_size(handle)
        self._in = np.zeros(self.in_size)
        self._in[-13:] = _DEFAULT_BASE
        self._q, self._v = self._in[:nj], self._in[nj : 2 * nj]
        self._tau = self._in[2 * nj : 2 * nj + na]
        self._base = self._in[2 * nj + na :]
        self._base_default = True
        self._bind(0)
        self._step = functools.partial(lib.slo_step, handle)

    def _bind(self, m: int) -> None:
        self._out = np.zeros(self.n + m)
        self.r, self.tau_ext = self._out[: self.n], self._out[self.n :]
        self._lib.slo_bind(self._h, _ptr(self._in), _ptr(self._out))

    def __del__(self):
        if getattr(self, "_h", None):
            self._lib.slo_free(self._h)
            self._h = None

    def set_filter(self, b_p: np.ndarray, b_u: np.ndarray, a: np.ndarray) -> None:
        bp, bu, aa = (np.ascontiguousarray(x, dtype=float) for x in (b_p, b_u, a))
        self._lib.slo_set_filter(self._h, len(aa) - 1, _ptr(bp), _ptr(bu), _ptr(aa))

    def set_monitor(self, rows, bias, threshold, warmup_steps: int) -> None:
        """The collision check: τ_ext = −r[rows]; contact ⇔ ∃ j |τ_ext,j − bias_j| > threshold_j,
        never in the first ``warmup_steps`` steps (counted from the last :meth:`reset`)."""
        rows = np.ascontiguousarray(rows, dtype=np.int32)
        bias, thr = (np.ascontiguousarray(x, dtype=float) for x in (bias, threshold))
        self._lib.slo_set_monitor(self._h, rows.size, _ptr(rows), _ptr(bias), _ptr(thr), int(warmup_steps))
        self._bind(rows.size)

    def reset(self) -> None:
        self._lib.slo_reset(self._h)

    def step(self, q, v, tau, base_q=None, base_v=None) -> bool:
        try:
            self._q[:] = q
            self._v[:] = v
            self._tau[:] = tau
            if base_q is not None or base_v is not None:
                self._base[:] = _DEFAULT_BASE
                if base_q is not None:
                    self._base[:7] = base_q
                if base_v is not None:
                    self._base[7:] = base_v
                self._base_default = False
            elif not self._base_default:
                self._base[:] = _DEFAULT_BASE
                self._base_default = True
        except ValueError:
            raise ShapeMismatchError(
                f"one observer sample needs q and v of {self.nj} joints, tau of {self.na}"
                + (", base_q of 7 and base_v of 6" if self.floating else "")
                + f"; got q {np.shape(q)}, v {np.shape(v)}, tau {np.shape(tau)}") from None
        return self._step(1) == 1

    def inputs(self, Q, V, TAU, base_q=None, base_v=None) -> np.ndarray:
        """Rows of the kernel's input layout (N, in_size) for a whole series."""
        N = len(Q)
        IN = np.tile(self._in, (N, 1))
        IN[:, -13:] = _DEFAULT_BASE
        IN[:, : self.nj], IN[:, self.nj : 2 * self.nj] = Q, V
        IN[:, 2 * self.nj : 2 * self.nj + self.na] = TAU
        if base_q is not None:
            IN[:, -13:-6] = base_q
        if base_v is not None:
            IN[:, -6:] = base_v
        return IN

    def run(self, IN: np.ndarray, timed: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Steps over the rows ``IN`` of :meth:`inputs` in one C++ loop: (r (N, n), τ_ext (N, m),
        flags (N,), per-step wall time [ns] or None)."""
        IN = np.ascontiguousarray(IN, dtype=float)
        N, m = IN.shape[0], self.tau_ext.size
        R, TE, F = np.empty((N, self.n)), np.empty((N, m)), np.empty(N, dtype=np.int32)
        ns = np.empty(N) if timed else None
        rc = self._lib.slo_run(self._h, N, _ptr(IN), 1, _ptr(R), _ptr(TE), _ptr(F), None if ns is None else _ptr(ns))
        if rc < 0:
            raise RuntimeError("the observer kernel has no filter: set_filter first")
        return R, TE, F.astype(bool), ns

    def tree_states(self, IN: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio states (Q (N, nq), V (N, nv)) of the rows of :meth:`inputs`."""
        nq, nv = self._nq, self._nv
        IN = np.ascontiguousarray(IN, dtype=float)
        Q, V = np.empty((len(IN), nq)), np.empty((len(IN), nv))
        for i in range(len(IN)):
            self._lib.slo_tree_state(self._h, _ptr(IN[i]), 1, _ptr(Q[i]), _ptr(V[i]))
        return Q, V

    def bare(self, Q: np.ndarray, V: np.ndarray, values: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """The bare C++ computation of M, Cᵀv and g over Pinocchio states, timed per sample: (ns (N,),
        (N, nv² + 2 nv) [M upper, Cᵀv, g] when ``values``)."""
        Q, V = (np.ascontiguousarray(x, dtype=float) for x in (Q, V))
        ns = np.empty(len(Q))
        out = np.empty((len(Q), self._nv * (self._nv + 2))) if values else None
        self._lib.slo_bare(self._h, len(Q), _ptr(Q), _ptr(V), None if out is None else _ptr(out), _ptr(ns))
        return ns, out


def _describe(lib, dyn) -> "tuple[int | None, str | None, dict]":
    """A kernel observer of ``dyn`` (handle, None, sizes) or (None, the reason, {})."""
    from ..regressor.terms import ModelStructure

    if not callable(getattr(dyn, "kernel_spec", None)):
        return None, f"{type(dyn).__name__} (not a MomentumDynamics) runs in Python", {}
    s, spec = dyn.structure, dyn.kernel_spec()
    for name in ("joint_features", "coulomb_sign", "sliding_sign"):
        if getattr(type(s), name) is not getattr(ModelStructure, name):
            return None, f"{type(s).__name__}.{name} is not the kernel's friction model", {}
    model = dyn.model
    tree = native.tree_model(model)
    if isinstance(tree, str):
        return None, tree, {}
    inert = np.array([np.concatenate([[Y.mass], np.asarray(Y.lever).ravel(), np.asarray(Y.inertia).ravel()])
                      for Y in list(model.inertias)[1:]]).reshape(-1, 13)
    arm = np.ascontiguousarray(model.armature, dtype=float)
    grav = np.ascontiguousarray(np.asarray(model.gravity.linear), dtype=float)
    inert = np.ascontiguousarray(inert)
    h = lib.slo_new(tree, dyn.n, _ptr(inert), _ptr(arm), _ptr(grav))
    i32 = lambda x: np.ascontiguousarray(x, dtype=np.int32)  # noqa: E731
    if dyn.transmission:
        if model.nq != model.nv or len(model.joints) - 1 != model.nv:
            lib.slo_free(h)
            return None, "a transmission tree with multi-DoF or continuous joints runs in Python", {}
        tree_robot = dyn.tree
        nq = model.nq
        Gfull = np.zeros((tree_robot.nq, dyn.n))
        off = np.zeros(tree_robot.nq)
        for i, name in enumerate(tree_robot.joint_names):
            Gfull[tree_robot.q_index(name)] = s.G[i]
            off[tree_robot.q_index(name)] = s.offset[i]
        perm = spec["perm"]
        Gq, q0 = np.ascontiguousarray(Gfull[perm][:nq]), np.ascontiguousarray(off[perm][:nq])
        G, Md = np.ascontiguousarray(spec["G"], dtype=float), np.ascontiguousarray(spec["M_drive"], dtype=float)
        lib.slo_set_transmission(h, _ptr(Gq), _ptr(q0), _ptr(G), _ptr(Md))
        for d in s.drives:
            vals = spec["drive_values"][d.name]
            eps = d.smoothing if d.smoothing is not None else s.coulomb_smoothing
            g = np.ascontiguousarray(d.g, dtype=float)
            lib.slo_add_drive(h, _ptr(g), *(float(vals.get(k, 0.0)) for k in ("fv", "fc", "offset", "k", "k_rest")),
                              float(eps or 0.0), float(d.s0))
        return h, None, {"nj": dyn.n, "na": dyn.n, "floating": False}
    robot = s.robot
    names = list(robot.joint_names)
    jq = i32([robot.q_index(j) for j in names])
    jv = i32([robot.v_index(j) for j in names])
    jc = i32([robot.is_continuous(j) for j in names])
    act = i32(dyn.actuated_rows)
    lib.slo_set_joints(h, len(names), _ptr(jq), _ptr(jv), _ptr(jc), int(dyn.floating_base), act.size, _ptr(act))
    _add_joint_friction(lib, h, s, spec)
    for law, iq, iv in spec["presliding"]:
        if law.kind == "state":
            lib.slo_add_presliding(h, int(iq), int(iv), float(law.coef.get("fc", 0.0)), law.k, law.play)
    return h, None, {"nj": len(names), "na": act.size, "floating": bool(dyn.floating_base)}


def _add_joint_friction(lib, h, s, spec: dict) -> None:
    """The joint terms (fv, fc, stribeck, offset; armature and presliding are elsewhere) per term joint."""
    terms = list(s.joint_terms)
    if not terms:
        return
    joints = s.robot.term_joints
    phi = spec["phi"] * (s.term_mask if getattr(s, "per_joint_terms", None) is not None else 1.0)
    eps = [s.smoothing_of(j) for j in joints]
    rest = (getattr(s, "rest_velocity", None) or {})
    vs = s.stribeck_velocity or {}
    coef = lambda k, t: float(phi[k, terms.index(t)]) if t in terms else 0.0  # noqa: E731
    for k, (j, iv) in enumerate(zip(joints, spec["term_rows"])):
        lib.slo_add_joint_friction(h, int(iv), float(eps[k]), float(rest.get(j, 0.0)), float(vs.get(j, 1.0)),
                                   int(s.friction_law == "product"), coef(k, "fv"), coef(k, "fc"),
                                   coef(k, "stribeck"), coef(k, "offset"))


def native_observer(dyn, reference: "Callable | None" = None) -> "tuple[NativeObserver | None, str | None]":
    """(the kernel's observer of ``dyn``, None), or (None, why the Python step is used). With a
    ``reference`` (``reference(dyn, gain, order, dt)``: the Python observer, e.g.
    ``MomentumObserver(dyn, gain=gain, order=order, dt=dt, compiled=False)``) the kernel's steps must
    equal the reference's on random states (relative 1e-9; checked once per dynamics object)."""
    lib = _lib()
    if lib is None:
        if native.library() is None:
            return None, native.unavailable_reason()
        return None, ("the C++ kernel was built before the observer step: rebuild it "
                      "(python -m sensorless.regressor.native_build)")
    h, reason, sizes = _describe(lib, dyn)
    if h is None:
        return None, reason
    obs = NativeObserver(lib, h, dyn.n, sizes["nj"], sizes["na"], sizes["floating"], dyn.model.nq, dyn.model.nv)
    if reference is not None:
        if dyn not in _CHECKED:
            _CHECKED[dyn] = _check(dyn, reference)
        verdict = _CHECKED[dyn]
        if verdict is not None:
            return None, verdict
    return obs, None


def _check(dyn, reference: Callable, samples: int = 12) -> "str | None":
    """None when the kernel's steps equal the Python ``reference`` observer's on random states, else the reason."""
    from ..data.integral_filter import observer_filter

    rng = np.random.default_rng(0)
    states = random_states(dyn, samples, rng)
    ref = reference(dyn, 40.0, 2, 1e-3)
    nat, _ = native_observer(dyn)
    nat.set_filter(*observer_filter(40.0, 2, 1e-3))
    worst = 0.0
    for q, v, tau, bq, bv in zip(*states):
        r_py = ref.step(q, v, tau, bq, bv)
        nat.step(q, v, tau, bq, bv)
        scale = max(1.0, float(np.abs(r_py).max()))
        if not np.all(np.isfinite(nat.r)):
            return "the kernel's step gave non-finite values on random states"
        worst = max(worst, float(np.abs(nat.r - r_py).max()) / scale)
    if worst > 1e-9:
        return f"the kernel's step differs from the Python step by {worst:.2g} (relative) on random states"
    return None


def random_states(dyn, N: int, rng: np.random.Generator):
    """N random samples (q, v, τ, base_q, base_v) of ``dyn``'s step inputs (base None without a
    floating base): positions within the limits, velocities over five decades (rest, the Coulomb
    transition, sliding) and some exact zeros."""
    if dyn.transmission:
        nj = na = dyn.n
        lo, hi = -0.5 * np.ones(nj), 0.5 * np.ones(nj)
    else:
        robot = dyn.structure.robot
        nj, na = len(robot.joint_names), len(dyn.actuated_rows)
        lo, hi = robot.position_limits()
        lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    q = lo + (hi - lo) * rng.uniform(size=(N, nj))
    scale = 10.0 ** rng.uniform(-4, 0.5, size=(N, nj))
    v = rng.standard_normal((N, nj)) * scale
    v[rng.uniform(size=(N, nj)) < 0.05] = 0.0
    tau = rng.standard_normal((N, na)) * 5.0
    if getattr(dyn, "floating_base", False):
        quat = rng.standard_normal((N, 4))
        quat /= np.linalg.norm(quat, axis=1, keepdims=True)
        base_q = np.column_stack([rng.uniform(-1, 1, (N, 2)), rng.uniform(0.2, 0.4, N), quat])
        base_v = rng.standard_normal((N, 6)) * 0.3
        return q, v, tau, base_q, base_v
    return q, v, tau, [None] * N, [None] * N

"""Generalised-momentum observer: external joint torques without joint accelerations.

With p = M(q) v and Pinocchio's Coriolis matrix C (Ṁ = C + Cᵀ),

    M v̇ + C v + g + τ_f(v) = τ + τ_ext   ⇒   ṗ = τ + β(q, v) + τ_ext,   β = Cᵀ v − g − τ_f.

The first-order observer (De Luca & Mattone 2003) is

    r(t) = K ( p(t) − p(0) − ∫₀ᵗ (τ + β + r) ds ),

i.e. ṙ = K (τ_ext − r): r is τ_ext through the low-pass L(s) = K / (s + K), and it needs
only q, v and τ. In transfer-function form, with e = p − p(0) and u = τ + β,

    r = s L(s) [e] − L(s) [u].

The second-order (filtered) variant uses L(s) = ω² / (s² + 2ζω s + ω²) (ω = K): the same
identity with a steeper roll-off on measurement noise. Both are discretised by the
bilinear (Tustin) transform — the trapezoidal rule of the integral above — and run either
on a whole log (:meth:`MomentumObserver.run`, scipy ``lfilter``) or one sample at a time
(:meth:`MomentumObserver.step`, in the C++ kernel when it is built: :mod:`.native_observer`); all give
the same numbers.

M, C and g come from Pinocchio (``crba``, ``computeCoriolisMatrix``,
``computeGeneralizedGravity``) on a copy of the model whose inertias and armature are the
*identified* ones (:class:`MomentumDynamics`), τ_f from the identified joint terms
(viscous, Coulomb, offset). A dynamics object may carry a friction *state* (a friction-only
model, :class:`~sensorless.estimation.friction_dynamics.FrictionDynamics`): its
``friction_integrator()`` gives the state, which :meth:`MomentumObserver.step` advances every
sample (β −= τ_f,state) and which ``momentum_series`` integrates along a whole log. Coordinates:

* fixed-base arm: the nv joint velocities (τ = Sᵀ τ_actuated);
* floating base: nv = 6 + n_joints (base twist in the base frame, Pinocchio LOCAL); the
  base rows of r are the external wrench on the base, τ_ext = Σ Jcᵀ f in stance;
* transmission (q = Gθ + q₀, e.g. the dVRK PSM in motor coordinates θ):
  M_θ = Gᵀ M G + Σ_d I_d g_d g_dᵀ, C_θ = Gᵀ C(q, Gθ̇) G, g_θ = Gᵀ g, τ_f,θ = Σ_d g_d f_d(θ, θ̇).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy import signal

from ..data.integral_filter import observer_filter
from ..data.trajectory import Trajectory
from ..regressor.friction_state import FrictionLaw, FrictionStateIntegrator
from ..errors import DataError, RobotModelError, ShapeMismatchError, TimestampError
from ..parameters import pin_inertia

__all__ = ["MomentumDynamics", "MomentumObserver", "ObserverResult", "depth_first_model"]


def depth_first_model(model: pin.Model) -> tuple[pin.Model, np.ndarray]:
    """The same tree with joints renumbered in depth-first order, and ``perm`` (new v → old v).

    Pinocchio's ``crba`` and ``computeCoriolisMatrix`` assume each joint's subtree occupies
    consecutive velocity indices (depth-first numbering); a tree built by ``addJoint`` in
    another order (e.g. the dVRK PSM tree) silently gets a wrong M and C, while RNEA and the
    regressor stay right. Only 1-DoF joints below the root are renumbered; an already
    depth-first model is returned as is (``perm`` = identity).
    """
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(sorted(children[j], reverse=True))
    if order == list(range(model.njoints)):
        return model, np.arange(model.nv)
    if any(model.joints[j].nv != 1 or model.joints[j].nq != 1 for j in range(1, model.njoints)):
        raise RobotModelError("the kinematic tree is not numbered depth-first and has multi-DoF joints; "
                              "Pinocchio's crba/computeCoriolisMatrix would be wrong on it")
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    ids = {0: 0}
    for j in order[1:]:
        jid = new.addJoint(ids[model.parents[j]], model.joints[j], model.jointPlacements[j], model.names[j])
        new.appendBodyToJoint(jid, model.inertias[j], pin.SE3.Identity())
        ids[j] = jid
    perm = np.empty(model.nv, dtype=int)
    for j_old, j_new in ids.items():
        if j_old:
            perm[new.joints[j_new].idx_v] = model.joints[j_old].idx_v
    new.armature[:] = np.asarray(model.armature)[perm]
    return new, perm


def _sym(M: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from Pinocchio's (possibly upper-triangular) M."""
    return np.triu(M) + np.triu(M, 1).T


class MomentumDynamics:
    """M(q), p = M v and β = Cᵀv − g − τ_f of an identified model, in observer coordinates.

    Build it from an identification structure and its parameter vector (or with
    :meth:`from_result` from a ``result.json``). Supported structures:
    :class:`~sensorless.regressor.ModelStructure` (fixed or floating base, incl.
    :class:`~sensorless.regressor.contact.ContactStructure`) and
    :class:`~sensorless.regressor.transmission.TransmissionStructure`.
    """

    def __init__(self, structure, params: np.ndarray) -> None:
        params = np.asarray(params, dtype=float)
        if params.shape != (structure.n_params,):
            raise ShapeMismatchError(f"expected {structure.n_params} parameters for this structure, got {params.shape}")
        self.structure, self.params = structure, params
        self.transmission = structure.robot.transmission_matrix is not None  # coordinates θ, tree q = Gθ + q₀
        nb = structure.n_body_params
        if self.transmission:
            tree = structure.tree
            model = tree.model.copy()
            model.armature[:] = 0.0  # drive inertias are added in coordinate space
            ids = structure.robot.body_indices
            for j in range(1, model.njoints):
                model.inertias[j] = pin.Inertia.Zero()
            for k, b in enumerate(ids):
                model.inertias[int(b) + 1] = pin_inertia(params[10 * k : 10 * k + 10])
            model, perm = depth_first_model(model)
            self.tree = tree
            self._perm = perm
            self.G = structure.G[perm]
            self.names = tuple(structure.coordinates)
            self.floating_base = False
            self._drive_values = structure.drive_values(params)
            self._M_drive = sum(
                (self._drive_values[d.name].get("inertia", 0.0) * np.outer(d.g, d.g) for d in structure.drives),
                np.zeros((len(self.names),) * 2),
            )
        else:
            robot = structure.robot
            if nb:
                robot = robot.with_inertial_parameters(params[:nb])
            model = robot.model.copy()
            r = structure.robot
            act, terms = r.actuated_v_indices, r.term_v_indices  # term joints: actuated, then passive
            model.armature[terms] = 0.0
            if "armature" in structure.joint_terms:
                model.armature[terms] = [params[structure.joint_term_index(j, "armature")]
                                         if "armature" in structure.terms_of(j) else 0.0 for j in r.term_joints]
            self.tree = structure.robot
            self.floating_base = structure.robot.floating_base
            base = [f"base_{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")] if self.floating_base else []
            self.names = tuple(base + list(structure.robot.joint_names))
            self._act, self._terms = act, terms
            nt, n = len(structure.joint_terms), len(r.term_joints)
            self._phi = params[nb:nb + n * nt].reshape(n, nt) if nt else np.zeros((n, 0))
            self._iq = np.array([robot.model.joints[robot.joint_id(j)].idx_q for j in r.term_joints], dtype=int)
            self._state_laws = _presliding_laws(structure, params)
            if depth_first_model(model)[0] is not model:
                raise RobotModelError(f"{structure.robot.name}: joints are not numbered depth-first; "
                                      "Pinocchio's crba/computeCoriolisMatrix need it")
        self.model, self.data = model, model.createData()

    @classmethod
    def from_result(cls, result_json: str | Path, robot) -> "MomentumDynamics":
        """From a ``result.json`` of ``sensorless identify`` (or its directory) and the robot."""
        from ..identification.artifact import load_model_folder

        art = load_model_folder(result_json, robot)
        return cls(art.structure, art.parameters)

    # ---- sizes and inputs ---------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of generalised coordinates of the observer."""
        return len(self.names)

    @property
    def actuated_rows(self) -> np.ndarray:
        """Observer rows of the logged (actuated) joints/coordinates."""
        return np.arange(self.n) if self.transmission else self._act

    @property
    def actuated_names(self) -> list[str]:
        return [self.names[i] for i in self.actuated_rows]

    def _ordered(self, traj: Trajectory) -> Trajectory:
        robot = self.structure.robot
        if tuple(traj.joint_names) == tuple(robot.joint_names):
            return traj
        robot.joint_order(traj.joint_names, traj.source)
        return traj.select_joints(list(robot.joint_names))

    def arrays(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q, V, τ) of a log: Pinocchio/coordinate states (N, ·) and generalised forces (N, n)."""
        if traj.v is None:
            raise DataError("the momentum observer needs joint velocities 'v'", traj.source)
        if traj.tau is None:
            raise DataError("the momentum observer needs the joint torque/effort 'tau'", traj.source)
        tr = self._ordered(traj)
        if self.transmission:
            return tr.q.copy(), tr.v.copy(), tr.tau.copy()
        robot = self.structure.robot
        if self.floating_base and (tr.base_q is None or tr.base_v is None):
            raise DataError("a floating-base robot needs base_q and base_v in the log", traj.source)
        Q = robot.full_configuration(tr.q, tr.base_q)
        V = robot.full_velocity(tr.v, tr.base_v)
        tau = np.zeros((len(tr), self.n))
        cols = [robot.joint_names.index(j) for j in robot.actuated_joints]
        tau[:, self._act] = tr.tau[:, cols]
        return Q, V, tau

    def step_arrays(self, q, v, tau, base_q=None, base_v=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, v, τ) of one sample in observer coordinates (joint arrays in ``joint_names`` order;
        τ of the actuated joints, or of all coordinates for a transmission)."""
        if self.transmission:
            return np.asarray(q, float), np.asarray(v, float), np.asarray(tau, float)
        robot = self.structure.robot
        qf = robot.full_configuration(np.asarray(q, float)[None], None if base_q is None else np.asarray(base_q)[None])[0]
        vf = robot.full_velocity(np.asarray(v, float)[None], None if base_v is None else np.asarray(base_v)[None])[0]
        tf = np.zeros(self.n)
        tf[self.actuated_rows] = tau
        return qf, vf, tf

    # ---- dynamics -----------------------------------------------------------------------
    def friction(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """τ_f (n,) or (N, n): identified joint/drive terms at zero acceleration."""
        q2, v2 = np.atleast_2d(q), np.atleast_2d(v)
        out = np.zeros((v2.shape[0], self.n))
        s = self.structure
        if self.transmission:
            for d in s.drives:
                vals = {k: val for k, val in self._drive_values[d.name].items() if k != "inertia"}
                out += d.force(vals, q2, v2, np.zeros_like(v2), s.coulomb_smoothing)[:, None] * d.g[None, :]
        elif self._phi.shape[1]:
            Z = np.zeros((v2.shape[0], len(self._terms))) if "presliding" in s.joint_terms else None  # carried apart
            F = s.joint_features(v2, np.zeros_like(v2), Z)  # (N, n_term_joints, n_terms); armature column is 0
            out[:, self._terms] = np.einsum("nkt,kt->nk", F, self._phi)
        return out if np.ndim(v) == 2 else out[0]

    def _tree_q(self, theta: np.ndarray) -> np.ndarray:
        """Tree configuration (depth-first numbering) of coordinates θ."""
        return self.tree.full_configuration(self.structure.joint_values(theta))[0][self._perm]

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) (n, n) in observer coordinates (identified inertias + armature/drive inertia)."""
        if self.transmission:
            qt = self._tree_q(q)
            return self.G.T @ _sym(pin.crba(self.model, self.data, qt)) @ self.G + self._M_drive
        return _sym(pin.crba(self.model, self.data, q))

    def momentum_terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, β) at one state: p = M v, β = Cᵀ v − g − τ_f (Pinocchio, no accelerations)."""
        model, data = self.model, self.data
        if self.transmission:
            qt = self._tree_q(q)
            vt = self.G @ v
            M = self.G.T @ _sym(pin.crba(model, data, qt)) @ self.G + self._M_drive
            C = pin.computeCoriolisMatrix(model, data, qt, vt)
            g = pin.computeGeneralizedGravity(model, data, qt)
            beta = self.G.T @ (C.T @ vt - g)
        else:
            M = _sym(pin.crba(model, data, q))
            C = pin.computeCoriolisMatrix(model, data, q, v)
            g = pin.computeGeneralizedGravity(model, data, q)
            beta = C.T @ v - g
        return M @ v, beta - self.friction(q, v)

    def momentum_series(self, Q: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, β), each (N, n), along a log (one set of Pinocchio calls per sample)."""
        N = Q.shape[0]
        P, B = np.empty((N, self.n)), np.empty((N, self.n))
        for i in range(N):
            P[i], B[i] = self.momentum_terms(Q[i], V[i])
        if getattr(self, "_state_laws", None):  # the presliding friction, its state integrated from 0
            B[:, self._terms] -= np.column_stack([law.torque(Q[:, iq], V[:, iv]) for law, iq, iv
                                                  in zip(self._state_laws, self._iq, self._terms)])
        return P, B

    def kernel_spec(self) -> dict:
        """What the compiled step (:mod:`.native_observer`) needs besides ``model``: the transmission's
        maps and drive values, or the joint-term rows and coefficients and the presliding laws."""
        if self.transmission:
            return {"perm": self._perm, "G": self.G, "M_drive": self._M_drive, "drive_values": self._drive_values}
        laws = self._state_laws or []
        return {"term_rows": self._terms, "phi": self._phi, "presliding": list(zip(laws, self._iq, self._terms))}

    def friction_integrator(self) -> "_StateFriction | None":
        """The presliding friction, streaming from the zero state, for :meth:`MomentumObserver.step`
        (None without a ``presliding`` term): the same numbers as :meth:`momentum_series`."""
        return _StateFriction(self) if getattr(self, "_state_laws", None) else None


def _presliding_laws(structure, params: np.ndarray) -> "list[FrictionLaw] | None":
    """Per term joint, the ``presliding`` term f_p s_c as a state :class:`FrictionLaw` (a joint without
    it: an empty static law, 0); None when no joint has the term."""
    if "presliding" not in structure.joint_terms:
        return None
    out = []
    for j in structure.robot.term_joints:
        if "presliding" in structure.terms_of(j):
            p = structure.presliding[j]
            coef = {"fc": float(params[structure.joint_term_index(j, "presliding")])}
            out.append(FrictionLaw("state", coef, k=p["k"], play=p["play"]))
        else:
            out.append(FrictionLaw("static", {}))
    return out


class _StateFriction:
    """The presliding friction of :class:`MomentumDynamics` one sample at a time (observer rows)."""

    def __init__(self, dyn: MomentumDynamics) -> None:
        self.dyn, self.integrator = dyn, FrictionStateIntegrator(dyn._state_laws)

    def step(self, qf: np.ndarray, vf: np.ndarray) -> np.ndarray:
        out = np.zeros(self.dyn.n)
        out[self.dyn._terms] = self.integrator.step(np.asarray(qf)[self.dyn._iq], np.asarray(vf)[self.dyn._terms])
        return out


@dataclass
class ObserverResult:
    """Observer output on a log: ``r`` (N, n) ≈ L(s)[τ_ext] in observer coordinates."""

    t: np.ndarray
    r: np.ndarray
    names: tuple[str, ...]
    p: np.ndarray
    beta: np.ndarray
    settings: dict = field(default_factory=dict)
    actuated_rows: np.ndarray | None = None

    @property
    def tau_ext(self) -> np.ndarray:
        """External torque on the actuated joints/coordinates (N, n_actuated)."""
        return self.r if self.actuated_rows is None else self.r[:, self.actuated_rows]


class MomentumObserver:
    """First- or second-order generalised-momentum observer (see module docstring).

    ``gain`` K [1/s] is the bandwidth of L(s); ``order`` 1 or 2; ``damping`` ζ of order 2.
    ``dt`` fixes the sample period of :meth:`step` (default: taken from the log in
    :meth:`run`, or required at the first :meth:`step`). ``compiled``: None runs :meth:`step` in
    the C++ kernel when it is built and accepts the model (:mod:`.native_observer`; same numbers),
    False forces Python, True requires the kernel (RobotModelError with the reason otherwise).
    """

    def __init__(self, dynamics: MomentumDynamics, gain: float = 50.0, order: int = 1, damping: float = 1.0,
                 dt: float | None = None, compiled: bool | None = None) -> None:
        self.dynamics, self.gain, self.order, self.damping = dynamics, float(gain), int(order), float(damping)
        observer_filter(self.gain, self.order, 1e-3, self.damping)  # validate settings now
        self.dt = dt
        self._want, self._native, self.compiled_reason = compiled, None, None
        self._fast = None
        if compiled:
            self.kernel()
        self.reset()

    @property
    def compiled(self) -> bool:
        """True when :meth:`step` runs in the C++ kernel (else ``compiled_reason`` says why). The first
        access builds and checks the kernel's copy of the model (milliseconds): do it before a loop."""
        return self.kernel() is not None

    def kernel(self):
        """The kernel's observer (:class:`~.native_observer.NativeObserver`), or None (Python step)."""
        if self._native is None and self.compiled_reason is None:
            if self._want is False:
                self.compiled_reason = "the Python step was asked for (compiled=False)"
            else:
                from .native_observer import native_observer

                self._native, self.compiled_reason = native_observer(self.dynamics, reference=_python_observer)
            if self._want and self._native is None:
                raise RobotModelError(f"the compiled observer step is not available: {self.compiled_reason}")
        return self._native

    def get_params(self) -> dict:
        return {"gain": self.gain, "order": self.order, "damping": self.damping, "dt": self.dt}

    # ---- offline --------------------------------------------------------------------------
    def run(self, traj: Trajectory) -> ObserverResult:
        """Observer output on a whole log (vectorised filtering; Pinocchio per sample)."""
        dt = _uniform_dt(traj) if self.dt is None else self.dt
        Q, V, tau = self.dynamics.arrays(traj)
        P, B = self.dynamics.momentum_series(Q, V)
        return self.from_terms(traj.t, P, B, tau, dt)

    def from_terms(self, t: np.ndarray, P: np.ndarray, B: np.ndarray, tau: np.ndarray, dt: float) -> ObserverResult:
        """Observer output from precomputed p, β and generalised forces τ, each (N, n)."""
        b_p, b_u, a = observer_filter(self.gain, self.order, dt, self.damping)
        r = signal.lfilter(b_p, a, P - P[:1], axis=0) - signal.lfilter(b_u, a, tau + B, axis=0)
        return ObserverResult(np.asarray(t, float), r, self.dynamics.names, P, B,
                              {**self.get_params(), "dt": dt}, self.dynamics.actuated_rows)

    # ---- streaming ------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the state: the next :meth:`step` sets p(0)."""
        self._p0 = None
        self._zp = self._zu = None
        self._coef = None
        self._fast = None
        if self._native is not None:
            self._native.reset()
        make = getattr(self.dynamics, "friction_integrator", None)
        self._friction = make() if make is not None else None

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, base_q: np.ndarray | None = None,
             base_v: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """One sample (joint arrays in the robot's ``joint_names`` order; τ of the actuated
        joints, or of all coordinates for a transmission) → r (n,). In the C++ kernel when
        :attr:`compiled`, else in Python: the same numbers (to 1e-10)."""
        fast = self._fast if self._fast is not None else self.prepare(dt)
        if fast is not None:
            fast.step(q, v, tau, base_q, base_v)
            return fast.r.copy()
        return self._step_python(q, v, tau, base_q, base_v)

    def step_into(self, out: np.ndarray, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                  base_q: np.ndarray | None = None, base_v: np.ndarray | None = None,
                  dt: float | None = None) -> np.ndarray:
        """:meth:`step` writing r into ``out`` (a float64 array of n) and returning it: no allocation
        per call on the compiled path, the fastest entry point for a control loop."""
        fast = self._fast if self._fast is not None else self.prepare(dt)
        if fast is not None:
            fast.step(q, v, tau, base_q, base_v)
            out[:] = fast.r
        else:
            out[:] = self._step_python(q, v, tau, base_q, base_v)
        return out

    def prepare(self, dt: float | None = None):
        """Settle what the first step would: the sample period ``dt`` (or the observer's), the filter and
        the kernel's copy of the model. Returns the kernel's observer when compiled, else None."""
        if self._coef is None:
            dt = dt or self.dt
            if not dt or dt <= 0:
                raise TimestampError("MomentumObserver.step needs the sample period dt at the first call")
            self.dt = dt
            self._coef = observer_filter(self.gain, self.order, dt, self.damping)
            kernel = self.kernel()
            if kernel is not None:
                kernel.set_filter(*self._coef)
                self._fast = kernel
        return self._fast

    def _step_python(self, q, v, tau, base_q=None, base_v=None) -> np.ndarray:
        dyn = self.dynamics
        qf, vf, tf = dyn.step_arrays(q, v, tau, base_q, base_v)
        p, beta = dyn.momentum_terms(qf, vf)
        if self._friction is not None:  # a friction state, integrated sample by sample
            beta = beta - self._friction.step(qf, vf)
        b_p, b_u, a = self._coef
        if self._p0 is None:
            self._p0 = p.copy()
            k = len(a) - 1
            self._zp, self._zu = np.zeros((k, dyn.n)), np.zeros((k, dyn.n))
        yp = _df2t(b_p, a, p - self._p0, self._zp)
        yu = _df2t(b_u, a, tf + beta, self._zu)
        return yp - yu


def _python_observer(dyn, gain: float, order: int, dt: float) -> MomentumObserver:
    """The Python step the compiled one is checked against (:func:`~.native_observer.native_observer`)."""
    return MomentumObserver(dyn, gain=gain, order=order, dt=dt, compiled=False)


def _df2t(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """One step of scipy's lfilter (direct form II transposed, a[0] = 1), state z updated in place."""
    y = b[0] * x + z[0]
    k = len(a) - 1
    for i in range(k - 1):
        z[i] = b[i + 1] * x + z[i + 1] - a[i + 1] * y
    z[k - 1] = b[k] * x - a[k] * y
    return y


def _uniform_dt(traj: Trajectory, tol: float = 0.25) -> float:
    """Median sample period; TimestampError if the log is not (nearly) uniformly sampled."""
    if len(traj) < 2:
        raise DataError("the log has fewer than 2 samples", traj.source)
    d = np.diff(traj.t)
    dt = float(np.median(d))
    bad = np.flatnonzero(np.abs(d - dt) > tol * dt)
    if dt <= 0 or bad.size:
        i = int(bad[0]) + 1 if bad.size else 1
        raise TimestampError(
            f"{traj.source}: the observer needs uniform sampling; sample {i} is {d[i - 1]:.4g} s after the previous "
            f"one (median period {dt:.4g} s)"
        )
    return dt

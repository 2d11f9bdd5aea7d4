"""A friction-only model of one or more joints (no body model), for test-bench logs.

Each joint gets its own law, static or with a state (:mod:`.friction_fit`), fitted on the
joint's samples of every training log. On a log with an output torque (``extras["tau_out"]``) and a
drive input (the current, or τ) a law is a drive law: it predicts the output torque from the drive
input (:meth:`~sensorless.regressor.friction_state.FrictionLaw.output_torque`), and that is what is
measured (:func:`measured_torque`). :class:`FrictionModel` has the estimator interface of the
package (``fit(trajectories) -> self``, ``predict(trajectory) -> τ̂``); a prediction integrates
each state law along the log from the zero state (:meth:`~sensorless.regressor.friction_state.FrictionLaw.torque`),
and :meth:`FrictionModel.integrator` does the same one sample at a time (an observer).

**Error near reversals.** A velocity reversal is a sign change of v between two samples where
|v| exceeds a threshold δ (default 5 velocity-noise stds, :func:`reversal_threshold`; a rest in
between belongs to the reversal). The samples within ``window`` seconds of the span from the last
sample before the reversal to the first one after it are *near the reversal*
(:func:`reversal_mask`); :func:`friction_errors` gives the RMSE there and over the whole log.
"""

from __future__ import annotations

from typing import Callable, Iterable, Sequence

import numpy as np

from ..data.rest import REST_SIGMAS, signal_noise
from ..data.trajectory import Trajectory
from ..errors import DataError, JointNameError, OptionError, setting
from .friction_fit import CHOICES, DEFAULT_TERMS, STATE_MODES, JointFit, fit_joint_friction, joint_series
from ..regressor.friction_state import FrictionLaw, FrictionStateIntegrator

__all__ = ["DEFAULT_REVERSAL_WINDOW", "FrictionModel", "friction_errors", "measured_torque", "reversal_mask",
           "reversal_threshold"]

#: seconds on each side of a reversal counted as "near" it
DEFAULT_REVERSAL_WINDOW = 1.0


class FrictionModel:
    """Per-joint friction laws fitted on bench logs (module docstring).

    ``terms``: the linear terms (:data:`~.friction_fit.DEFAULT_TERMS`; ``stribeck`` and the
    state are kept only where BIC supports them); ``state``: "auto" | "on" | "off";
    ``coulomb_smoothing``: "auto" (3 velocity-noise stds) or ε; ``joints``: the joints to fit
    (default: every joint of the first log); ``choice``: how optional terms and the state are chosen,
    "held-out" (blocked held-out error across logs) or "bic". Fitted: ``laws_`` / ``static_laws_`` {joint: law},
    ``fits_`` {joint: :class:`~.friction_fit.JointFit`}, ``joint_names_``.
    """

    def __init__(self, terms: Sequence[str] = DEFAULT_TERMS, state: str = "auto",
                 coulomb_smoothing: "str | float" = "auto", joints: "Sequence[str] | None" = None,
                 choice: str = "held-out") -> None:
        if state not in STATE_MODES:
            raise OptionError(f"{setting('state')} must be one of {', '.join(STATE_MODES)}, got {state!r}")
        if not (coulomb_smoothing == "auto" or (isinstance(coulomb_smoothing, (int, float))
                                                and np.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0)):
            raise OptionError(f"{setting('coulomb_smoothing')} must be 'auto' or a number >= 0, got {coulomb_smoothing!r}")
        if choice not in CHOICES:
            raise OptionError(f"the choice must be one of {', '.join(CHOICES)}, got {choice!r}")
        self.terms, self.state, self.coulomb_smoothing, self.choice = tuple(terms), state, coulomb_smoothing, choice
        self.joints = None if joints is None else tuple(joints)

    def get_params(self) -> dict:
        return {"terms": list(self.terms), "state": self.state, "coulomb_smoothing": self.coulomb_smoothing,
                "joints": None if self.joints is None else list(self.joints), "choice": self.choice}

    def fit(self, trajectories: Iterable[Trajectory], progress: Callable[[int, int], None] | None = None
            ) -> "FrictionModel":
        """Fit each joint's law on every log; ``progress(done, n_joints)`` after each joint."""
        logs = list(trajectories)
        if not logs:
            raise DataError("no log to fit the friction on")
        joints = list(self.joints or logs[0].joint_names)
        for tr in logs:
            missing = [j for j in joints if j not in tr.joint_names]
            if missing:
                raise JointNameError(f"joint(s) {missing} are not in the log (it has {list(tr.joint_names)})",
                                     tr.source)
        from ..regressor.normal_equations import one_blas_thread  # small products: threaded BLAS only waits

        self.fits_: dict[str, JointFit] = {}
        with one_blas_thread():
            for k, j in enumerate(joints):
                self.fits_[j] = fit_joint_friction([joint_series(tr, j) for tr in logs], joint=j, terms=self.terms,
                                                   state=self.state, coulomb_smoothing=self.coulomb_smoothing,
                                                   choice=self.choice)
                if progress is not None:
                    progress(k + 1, len(joints))
        self.joint_names_ = tuple(joints)
        self.laws_ = {j: f.law for j, f in self.fits_.items()}
        self.static_laws_ = {j: f.static for j, f in self.fits_.items()}
        return self

    @classmethod
    def from_laws(cls, laws: "dict[str, FrictionLaw]", static_laws: "dict[str, FrictionLaw] | None" = None,
                  **params) -> "FrictionModel":
        """A fitted model from stored laws (:func:`~sensorless.identification.artifact.load_friction_model`)."""
        m = cls(**params)
        m.joint_names_ = tuple(laws)
        m.laws_ = dict(laws)
        m.static_laws_ = dict(static_laws or {})
        m.fits_ = {}
        return m

    def _check(self, traj: Trajectory) -> list[int]:
        if not hasattr(self, "laws_"):
            raise DataError("the friction model is not fitted")
        missing = [j for j in self.joint_names_ if j not in traj.joint_names]
        if missing:
            raise JointNameError(f"joint(s) {missing} of the friction model are not in the log "
                                 f"(it has {list(traj.joint_names)})", traj.source)
        if traj.v is None:
            raise DataError("predicting friction needs the joint velocities", traj.source)
        return [list(traj.joint_names).index(j) for j in self.joint_names_]

    def predict(self, traj: Trajectory, *, static: bool = False) -> np.ndarray:
        """τ̂ (N, n_joints) in ``joint_names_`` order, states from 0; ``static``: the best static laws. A
        drive law's τ̂ is the output torque from the drive input alone (never from the logged output)."""
        cols = self._check(traj)
        laws = self.static_laws_ if static else self.laws_
        out = np.empty((len(traj), len(cols)))
        for k, (j, c) in enumerate(zip(self.joint_names_, cols)):
            law = laws[j]
            a = None if traj.a is None else traj.a[:, c]
            if "inertia" in law.coef and a is None:
                raise DataError(f"the friction law of '{j}' has an inertia term; the log needs v̇", traj.source)
            if law.is_drive:
                u = traj.extras.get("current", traj.tau)
                if u is None:
                    raise DataError(f"the friction law of '{j}' maps a drive input to the output torque; the log "
                                    f"needs the current (or input torque) of '{j}'", traj.source)
                qm = traj.extras.get("q_motor")
                if "stiffness_motor" in law.coef and qm is None:
                    raise DataError(f"the friction law of '{j}' has a transmission stiffness; the log needs the "
                                    f"motor-side position (q_motor) of '{j}'", traj.source)
                out[:, k] = law.output_torque(traj.q[:, c], traj.v[:, c], a, drive=np.asarray(u, dtype=float)[:, c],
                                              motor=None if qm is None else np.asarray(qm, dtype=float)[:, c])
            else:
                out[:, k] = law.torque(traj.q[:, c], traj.v[:, c], a)
        return out

    def friction_pair(self, traj: Trajectory, *, static: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(measured, modelled) friction (N, n_joints): τ and τ̂ of a plain law; of a drive law what its
        drive terms deliver minus the measured and the predicted output torque (the friction the
        transmission takes)."""
        pred = self.predict(traj, static=static)
        cols = self._check(traj)
        meas = np.column_stack([measured_torque(traj, j) for j in self.joint_names_])
        laws = self.static_laws_ if static else self.laws_
        for k, (j, c) in enumerate(zip(self.joint_names_, cols)):
            law = laws[j]
            if law.is_drive:
                u = np.asarray(traj.extras.get("current", traj.tau), dtype=float)[:, c]
                qm = traj.extras.get("q_motor")
                d = law.drive_torque(traj.q[:, c], traj.v[:, c], drive=u,
                                     motor=None if qm is None else np.asarray(qm, dtype=float)[:, c])
                meas[:, k], pred[:, k] = d - meas[:, k], d - pred[:, k]
        return meas, pred

    def integrator(self) -> FrictionStateIntegrator:
        """A streaming evaluator of the laws (states from 0), in ``joint_names_`` order."""
        return FrictionStateIntegrator([self.laws_[j] for j in self.joint_names_])

    @property
    def has_state(self) -> bool:
        return any(law.kind == "state" for law in self.laws_.values())


def measured_torque(traj: Trajectory, joint: str) -> np.ndarray:
    """The torque a friction model predicts for ``joint`` of ``traj``: its output torque
    (``extras["tau_out"]``) when logged, else its τ."""
    c = list(traj.joint_names).index(joint)
    out = traj.extras.get("tau_out")
    if out is not None:
        return np.asarray(out, dtype=float)[:, c]
    if traj.tau is None:
        raise DataError(f"the log has no torque of '{joint}'", traj.source)
    return traj.tau[:, c]


def reversal_threshold(v: np.ndarray) -> float:
    """δ = :data:`~sensorless.data.rest.REST_SIGMAS` velocity-noise stds (at least 10⁻⁶ of P95 |v|)."""
    v = np.asarray(v, dtype=float).ravel()
    noise = float(signal_noise(v)[0]) if v.size > 30 else 0.0
    return max(REST_SIGMAS * noise, 1e-6 * float(np.percentile(np.abs(v), 95)) if v.size else 0.0)


def reversal_mask(t: np.ndarray, v: np.ndarray, *, window: float = DEFAULT_REVERSAL_WINDOW,
                  threshold: "float | None" = None) -> np.ndarray:
    """Samples within ``window`` s of a velocity reversal (module docstring), (N,) bool."""
    t, v = np.asarray(t, dtype=float).ravel(), np.asarray(v, dtype=float).ravel()
    if threshold is None:
        threshold = reversal_threshold(v)
    idx = np.flatnonzero(np.abs(v) > threshold)
    mask = np.zeros(t.size, dtype=bool)
    if idx.size < 2:
        return mask
    flips = np.flatnonzero(np.sign(v[idx[1:]]) != np.sign(v[idx[:-1]]))
    starts, ends = t[idx[flips]] - window, t[idx[flips + 1]] + window
    lo = np.searchsorted(t, starts, side="left")
    hi = np.searchsorted(t, ends, side="right")
    edges = np.zeros(t.size + 1, dtype=int)
    np.add.at(edges, lo, 1)
    np.add.at(edges, hi, -1)
    return np.cumsum(edges[:-1]) > 0


def friction_errors(measured: np.ndarray, predicted: np.ndarray, t: np.ndarray, v: np.ndarray, *,
                    window: float = DEFAULT_REVERSAL_WINDOW, threshold: "float | None" = None) -> dict:
    """RMSE over the log and near reversals (:func:`reversal_mask`) of one joint, [N·m or N]."""
    e = np.asarray(predicted, dtype=float).ravel() - np.asarray(measured, dtype=float).ravel()
    m = reversal_mask(t, v, window=window, threshold=threshold)
    return {"rmse": float(np.sqrt(np.mean(e**2))) if e.size else None,
            "rmse_reversals": float(np.sqrt(np.mean(e[m] ** 2))) if m.any() else None,
            "samples_near_reversals": int(m.sum()), "n_samples": int(e.size)}

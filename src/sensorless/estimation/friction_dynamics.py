"""Momentum-observer dynamics of a friction-only model (test-bench joints, no body model).

A bench joint's modelled dynamics are its inertia J (the law's ``inertia`` term; 0 without one)
and its friction, J v̇ + τ_f = τ + τ_ext, so with p = J v and β = −τ_f the observer of
:mod:`.momentum` (ṗ = τ + β + τ_ext) applies unchanged. τ_f carries the friction state
(:mod:`sensorless.regressor.friction_state`): :meth:`FrictionDynamics.momentum_series`
integrates it along a whole log and :meth:`FrictionDynamics.friction_integrator` gives the
streaming state that :meth:`~.momentum.MomentumObserver.step` advances sample by sample, both from
the zero state, so ``run`` and ``step`` give the same numbers.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, JointNameError
from ..regressor.friction_state import FrictionStateIntegrator

__all__ = ["FrictionDynamics"]


class FrictionDynamics:
    """Observer dynamics (the interface of :class:`~.momentum.MomentumDynamics`) of a fitted
    :class:`~sensorless.identification.friction_model.FrictionModel`; coordinates are its joints."""

    transmission = False
    floating_base = False

    def __init__(self, model) -> None:
        self.model = model
        self.names = tuple(model.joint_names_)
        laws = [model.laws_[j] for j in self.names]
        drives = [j for j, law in zip(self.names, laws) if law.is_drive]
        if drives:
            raise DataError(f"the friction model of {drives} is a drive's (its gain fitted from the current and the "
                            "output torque): it predicts the output torque, and the momentum observer does not take "
                            "such a model; predict it with `sensorless predict`")
        self.inertia = np.array([law.coef.get("inertia", 0.0) for law in laws])
        self._laws = [dataclasses.replace(law, coef={k: v for k, v in law.coef.items() if k != "inertia"})
                      for law in laws]

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def actuated_rows(self) -> np.ndarray:
        return np.arange(self.n)

    @property
    def actuated_names(self) -> list[str]:
        return list(self.names)

    def arrays(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q, V, τ) of a log, each (N, n) in the model's joint order."""
        missing = [j for j in self.names if j not in traj.joint_names]
        if missing:
            raise JointNameError(f"joint(s) {missing} of the friction model are not in the log", traj.source)
        if traj.v is None or traj.tau is None:
            raise DataError("the momentum observer needs the joint velocities and torques", traj.source)
        cols = [list(traj.joint_names).index(j) for j in self.names]
        return traj.q[:, cols].copy(), traj.v[:, cols].copy(), traj.tau[:, cols].copy()

    def step_arrays(self, q, v, tau, base_q=None, base_v=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.asarray(q, float).ravel(), np.asarray(v, float).ravel(), np.asarray(tau, float).ravel()

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return np.diag(self.inertia)

    def friction(self, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
        """τ_f (N, n) along a log (states from zero; no inertia term)."""
        Q, V = np.atleast_2d(Q), np.atleast_2d(V)
        return np.column_stack([law.torque(Q[:, k], V[:, k]) for k, law in enumerate(self._laws)])

    def momentum_terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, β) of one sample without the friction, which the state integrator adds."""
        return self.inertia * np.asarray(v, float), np.zeros(self.n)

    def momentum_series(self, Q: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, β) along a log: p = J v, β = −τ_f with the state integrated from zero."""
        return self.inertia[None, :] * V, -self.friction(Q, V)

    def friction_integrator(self) -> FrictionStateIntegrator:
        """A fresh streaming friction (states at zero) for :meth:`~.momentum.MomentumObserver.step`."""
        return FrictionStateIntegrator(self._laws)

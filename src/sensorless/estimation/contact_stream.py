"""The collision monitor's per-sample work, streaming: one observer step and the threshold test,

    τ_ext = −r[rows]   (the sign of ``sensorless monitor``: what the robot exerts on its environment),
    contact  ⇔  ∃ j: |τ_ext,j − b_j| > thr_j,   never during the observer's warm-up

(b and thr = k σ per joint from a quiet window, :func:`~.collision.quiet_thresholds`; the warm-up
:func:`~.collision.observer_warmup`). With a compiled observer (:attr:`.MomentumObserver.compiled`) the
whole sample is one call into the C++ kernel, else the Python step; the flags are the same. The
rest-aware decisions of ``sensorless monitor`` (static-friction band, holding level) need whole rest
segments and stay offline.
"""

from __future__ import annotations

import numpy as np

from ..errors import JointNameError, ShapeMismatchError, TimestampError
from .collision import Thresholds, observer_warmup
from .momentum import MomentumObserver

__all__ = ["ContactStream"]


class ContactStream:
    """Per sample: :meth:`step` → contact flag; τ_ext (m,) of the rows ``names`` in :attr:`tau_ext` and
    the observer output r (n,) in :attr:`r` (buffers overwritten by the next step: copy to keep).
    ``warmup`` [s]: None for the observer's convergence time. The observer needs its ``dt``."""

    def __init__(self, observer: MomentumObserver, names, bias, threshold, warmup: float | None = None) -> None:
        dyn = observer.dynamics
        if not observer.dt or observer.dt <= 0:
            raise TimestampError("the streaming collision check needs the observer's sample period dt")
        unknown = [n for n in names if n not in dyn.names]
        if unknown:
            raise JointNameError(f"joint(s) {unknown} are not observer coordinates; they are {list(dyn.names)}")
        self.observer, self.names = observer, list(names)
        self.rows = np.array([dyn.names.index(n) for n in names], dtype=int)
        self.bias, self.threshold = (np.asarray(x, dtype=float).ravel() for x in (bias, threshold))
        if self.bias.shape != (len(names),) or self.threshold.shape != (len(names),):
            raise ShapeMismatchError(f"bias and threshold need one value per joint of {self.names}, "
                                     f"got {self.bias.size} and {self.threshold.size}")
        warm = observer_warmup(observer.gain, observer.order, observer.dt, observer.damping) if warmup is None \
            else float(warmup)
        self.warmup_steps = int(np.ceil(warm / observer.dt - 1e-9))
        self._kernel = observer.prepare()
        if self._kernel is not None:
            self._kernel.set_monitor(self.rows, self.bias, self.threshold, self.warmup_steps)
            self.r, self.tau_ext = self._kernel.r, self._kernel.tau_ext
        else:
            self.r, self.tau_ext = np.zeros(dyn.n), np.zeros(len(names))
        self._count = 0

    @classmethod
    def from_thresholds(cls, observer: MomentumObserver, th: Thresholds, warmup: float | None = None) -> "ContactStream":
        """From the :class:`~.collision.Thresholds` of a quiet window (names, bias, k σ)."""
        return cls(observer, th.names, th.bias, th.threshold, warmup)

    @property
    def compiled(self) -> bool:
        return self._kernel is not None

    def reset(self) -> None:
        """Restart the observer and the warm-up."""
        self.observer.reset()
        self._kernel = self.observer.prepare()
        self._count = 0

    def step(self, q, v, tau, base_q=None, base_v=None) -> bool:
        """One sample (the arguments of :meth:`.MomentumObserver.step`) → is there a contact?"""
        if self._kernel is not None:
            return self._kernel.step(q, v, tau, base_q, base_v)
        r = self.observer.step_into(self.r, q, v, tau, base_q, base_v)
        np.negative(r[self.rows], out=self.tau_ext)
        armed = self._count >= self.warmup_steps
        self._count += 1
        return bool(armed and np.any(np.abs(self.tau_ext - self.bias) > self.threshold))

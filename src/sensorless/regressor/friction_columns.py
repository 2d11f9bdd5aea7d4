"""Friction columns of the joint terms (:mod:`.terms`), per term joint j: viscous ``fv`` (v),
Coulomb ``fc`` (column T = tanh(v/ε_j), ε_j the joint's transition width; sgn v for
ε_j = 0), Stribeck ``stribeck`` (parameter fs − fc; column T − (1 − exp(−(v/vs_j)²)) sgn v),
constant ``offset`` and ``armature`` (reflected rotor inertia). Together (``friction_law``
"blend")

    τ_f = fs tanh(v/ε) − (fs − fc)(1 − e^{−(v/vs)²}) sgn v + fv v + o:

friction rises from 0 to the static level fs over the width ε, then decays to the Coulomb
level fc over vs (≥ 3 ε), plus viscous friction. ε and vs are fixed per joint here;
:mod:`sensorless.identification.friction` measures ε from the velocity noise and chooses
both from the data (:mod:`sensorless.identification.stribeck`). The two columns depend on ε
and vs separately (the decay (1 − e^{−(v/vs)²}) sgn v is continuous at 0 and needs no
smoothing), which lets one compression pass hold candidates for both. Models written before
(``friction_law`` "product", read from older result.json files) have the Stribeck column
e^{−(v/vs)²} tanh(v/ε): the same law up to (fs − fc)(1 − e^{−(v/vs)²})(T − sgn v), a few %
of fs − fc for |v| ≲ ε.

With a rest velocity δ_j > 0 (``rest_velocity``) the sign functions are 0 where
|v| ≤ δ_j: a joint whose velocity is within the noise of zero is at rest, and a joint
at rest has no sliding friction (static friction holds whatever is needed, 0 here), so
the model does not chatter through sgn(noise) at rest. The equations of a joint within
its rest velocity are also left out of the fit (:func:`fit_keep`): the
friction there is indeterminate (at rest static friction holds anything in ±fs, and a
slow motion lost in the noise has ±fs), so they would only bias the other parameters.
Likewise, for a joint with Coulomb or Stribeck friction, the equations of the two samples
around each velocity reversal (v changes sign between them) are left out: friction jumps
by ~2 fs within that sampling interval, and the torque logged there depends on where in
the interval the reversal fell and on the signal chain (current-loop and anti-aliasing
filters, resampling a jittered log), a blend of the two branches that no velocity law
predicts; fitted, those samples bias fc, fs and fv (on the simulated real-arm benchmark
they drove most of the held-out error left). Prediction still covers every sample, and
the friction law's search scores its candidates on them too
(:mod:`sensorless.identification.stribeck`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["coulomb_sign", "fit_keep", "sliding_sign", "stribeck_decay"]


def coulomb_sign(v: np.ndarray, eps: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """T per joint of velocities ``v`` (N, n): tanh(v/ε) (sgn v for ε = 0), 0 where |v| ≤ δ (``rest``)."""
    return np.where(eps > 0, np.tanh(v / np.where(eps > 0, eps, 1.0)), np.sign(v)) * (np.abs(v) > rest)


def sliding_sign(v: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """sgn v per joint of velocities ``v`` (N, n), 0 where |v| ≤ δ (``rest``)."""
    return np.sign(v) * (np.abs(v) > rest)


def stribeck_decay(v: np.ndarray, vs: np.ndarray, sgn: np.ndarray) -> np.ndarray:
    """(1 − e^{−(v/vs)²}) sgn v: the Stribeck decay from fs to fc (module docstring); ``vs``
    broadcasts against ``v``, ``sgn`` is the sign to use (0 at rest)."""
    return -np.expm1(-((v / vs) ** 2)) * sgn


def fit_keep(v: np.ndarray, rest: np.ndarray, law: np.ndarray) -> "np.ndarray | None":
    """(N, n) 0/1: is joint j's equation in the fit (module docstring)? 0 where |v| ≤ δ_j, and for
    a joint with Coulomb or Stribeck friction (``law``) at a sample next to a velocity reversal
    (v changes sign from the sample before or to the sample after, within ``v``); None when
    nothing is left out."""
    s = np.sign(v)
    flip = np.zeros(v.shape, dtype=bool)
    flip[1:] |= s[1:] * s[:-1] < 0
    flip[:-1] |= s[1:] * s[:-1] < 0
    flip &= np.asarray(law, dtype=bool)[None, :]
    still = (np.abs(v) <= rest[None, :]) & (rest[None, :] > 0)
    if not (flip.any() or still.any()):
        return None
    return (~flip & ~still).astype(float)

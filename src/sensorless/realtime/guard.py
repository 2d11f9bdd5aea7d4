"""What a live sample may be before the observer sees it: finite and inside the robot's physical range.

A sample with a non-finite value, a position beyond the model's joint limits (with a margin), a
velocity beyond its velocity limits or a torque beyond an effort bound is never fed to the
observer (one 1e300 torque would otherwise poison its integral for the rest of the stream). The
stream counts it, flags it (contact 1, estimates NaN: a safety function fails safe) and goes on.

Bounds (per field, :meth:`SampleGuard.for_robot`): position limits ± (5 % of the range + 0.02),
|v| ≤ 3× the velocity limit, |τ| ≤ 3× the effort limit, where the model gives them (finite and
> 0); every field |x| ≤ :data:`ABSOLUTE` otherwise.

The unit check (:meth:`SampleGuard.units`): at start-up, a sample out of range that fits once its
positions and velocities are taken as degrees (÷ 180/π) or its torques as ×1000 (÷ 1000) is a
:class:`~sensorless.errors.UnitsError` naming the field, not a stream of flags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import UnitsError

__all__ = ["ABSOLUTE", "SampleGuard"]

#: bound on |x| of any field when the model gives no limit for it
ABSOLUTE = 1e6
_DEG = 180.0 / math.pi


def _finite_positive(x: float) -> bool:
    return math.isfinite(x) and 0 < x < np.finfo(float).max / 4


@dataclass(frozen=True)
class SampleGuard:
    """Per-field bounds of an input sample (q, v, τ), in record order."""

    joints: tuple[str, ...]
    actuated: tuple[str, ...]
    q_lo: np.ndarray
    q_hi: np.ndarray
    v_max: np.ndarray
    tau_max: np.ndarray

    @classmethod
    def for_robot(cls, robot, joints, actuated) -> "SampleGuard":
        """Bounds from ``robot``'s limits (module docstring) for the record's ``joints`` and ``actuated``
        (``robot`` None: :data:`ABSOLUTE` only)."""
        names = tuple(robot.joint_names) if robot is not None else ()
        lo, hi = robot.position_limits() if robot is not None else ((), ())
        vl = robot.velocity_limits() if robot is not None else ()
        q_lo, q_hi = np.full(len(joints), -ABSOLUTE), np.full(len(joints), ABSOLUTE)
        v_max = np.full(len(joints), ABSOLUTE)
        for i, n in enumerate(joints):
            if n not in names:
                continue
            k = names.index(n)
            if np.isfinite(lo[k]) and np.isfinite(hi[k]) and hi[k] > lo[k]:
                m = 0.05 * (hi[k] - lo[k]) + 0.02
                q_lo[i], q_hi[i] = lo[k] - m, hi[k] + m
            if _finite_positive(float(vl[k])):
                v_max[i] = 3.0 * float(vl[k])
        tau_max = np.full(len(actuated), ABSOLUTE)
        for i, n in enumerate(actuated):
            if n in names:
                e = float(robot.model.effortLimit[robot.v_index(n)])
                if _finite_positive(e):
                    tau_max[i] = 3.0 * e
        return cls(tuple(joints), tuple(actuated), q_lo, q_hi, v_max, tau_max)

    def check(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> str | None:
        """None for an admissible sample; else what is wrong, naming the first bad field."""
        if np.isfinite(q).all() and np.isfinite(v).all() and np.isfinite(tau).all() and \
                (q >= self.q_lo).all() and (q <= self.q_hi).all() and (np.abs(v) <= self.v_max).all() and \
                (np.abs(tau) <= self.tau_max).all():
            return None
        for field, names, x, lo, hi in (("q", self.joints, q, self.q_lo, self.q_hi),
                                        ("v", self.joints, v, -self.v_max, self.v_max),
                                        ("tau", self.actuated, tau, -self.tau_max, self.tau_max)):
            for n, xi, a, b in zip(names, x, lo, hi):
                if not math.isfinite(xi):
                    return f"{field}[{n}] is {xi}"
                if not a <= xi <= b:
                    return f"{field}[{n}] = {xi:.6g} is outside [{a:.4g}, {b:.4g}]"
        return None

    def units(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> None:
        """UnitsError when an out-of-range sample fits as degrees or as torques ×1000 (module docstring)."""
        if not (np.isfinite(q).all() and np.isfinite(v).all() and np.isfinite(tau).all()):
            return
        tau_ok = (np.abs(tau) <= self.tau_max).all()
        qv_ok = (q >= self.q_lo).all() and (q <= self.q_hi).all() and (np.abs(v) <= self.v_max).all()
        if not qv_ok and (q / _DEG >= self.q_lo).all() and (q / _DEG <= self.q_hi).all() and \
                (np.abs(v / _DEG) <= self.v_max).all():
            bad = self.check(q, v, np.zeros_like(tau))
            raise UnitsError(f"the first samples are outside the joint limits and fit once taken as degrees ({bad}): "
                             "send positions in rad (m) and velocities in rad/s (m/s)")
        if qv_ok and not tau_ok and (np.abs(tau / 1000.0) <= self.tau_max).all():
            bad = self.check(q, v, tau)
            raise UnitsError(f"the first samples' torques are beyond the effort bound and fit once divided by 1000 "
                             f"({bad}): send torques in N·m (N), not mN·m")

    def settings(self) -> dict:
        """The bounds, as recorded in the stream summary."""
        f = lambda a: [float(x) for x in a]  # noqa: E731
        return {"q_min": f(self.q_lo), "q_max": f(self.q_hi), "v_abs_max": f(self.v_max), "tau_abs_max": f(self.tau_max)}

"""Excitation limits: joint position, velocity and acceleration bounds, Cartesian boxes, export
size checks, and the random baseline scaled to the limits.

The analytic worst-case bounds of a Fourier trajectory (triangle inequality over the harmonics,
amplitude √(a² + b²)) hold at every instant:

    q0 ± Σ_l amp_l / ω_l ∈ [lower, upper],   Σ_l amp_l ≤ v_max,   Σ_l ω_l amp_l ≤ a_max.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import ExcitationError, setting
from .fourier import FourierTrajectory

__all__ = [
    "CartesianBox",
    "ExcitationLimits",
    "check_export",
    "check_sampled_limits",
    "random_excitation",
    "robot_limits",
]

MAX_RATE_HZ = 100_000.0  # export sample rate bound
MAX_EXPORT_SAMPLES = 10_000_000  # samples in trajectory.npz


@dataclass
class ExcitationLimits:
    """Box limits per coordinate: position [lower, upper], |velocity|, |acceleration|."""

    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        self.joint_names = tuple(self.joint_names)
        for name in ("lower", "upper", "velocity", "acceleration"):
            val = np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (n,)).copy()
            if not np.all(np.isfinite(val)):
                raise ExcitationError(f"excitation limits: '{name}' must be finite for every joint, got {val}")
            setattr(self, name, val)
        bad = [j for j, lo, hi in zip(self.joint_names, self.lower, self.upper) if not lo < hi]
        if bad:
            raise ExcitationError(f"excitation limits: lower >= upper for joint(s) {bad}")
        bad = [j for j, v, a in zip(self.joint_names, self.velocity, self.acceleration) if v <= 0 or a <= 0]
        if bad:
            raise ExcitationError(f"excitation limits: velocity/acceleration limits must be > 0 (joint(s) {bad})")

    @classmethod
    def from_robot(
        cls,
        robot,
        position_fraction: float = 0.8,
        max_velocity: float | np.ndarray = 2.0,
        max_acceleration: float | np.ndarray = 10.0,
    ) -> ExcitationLimits:
        """The limits :func:`~sensorless.excitation.random_fourier` uses: ``position_fraction``
        of each joint's range about mid-range (±π for unlimited joints), velocity capped by
        the model's limit. ``0 < position_fraction ≤ 1`` (a fraction above 1 would leave the
        joint range); the velocity and acceleration limits must be finite and > 0."""
        if not (np.isfinite(position_fraction) and 0.0 < position_fraction <= 1.0):
            raise ExcitationError(f"position fraction ({setting('position_fraction')}) must be in (0, 1], got "
                                  f"{position_fraction}")
        for name, val in ((f"velocity ({setting('max_velocity')})", max_velocity),
                          (f"acceleration ({setting('max_acceleration')})", max_acceleration)):
            arr = np.asarray(val, dtype=float)
            if not (np.all(np.isfinite(arr)) and np.all(arr > 0)):
                raise ExcitationError(f"maximum {name} must be finite and > 0, got {val}")
        lo, hi = robot.position_limits()
        lo = np.where(np.isfinite(lo), lo, -np.pi)
        hi = np.where(np.isfinite(hi), hi, np.pi)
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * position_fraction
        n = len(lo)
        vlim = robot.velocity_limits()
        vmax = np.minimum(np.broadcast_to(max_velocity, (n,)), np.where(vlim > 0, vlim, np.inf))
        return cls(tuple(robot.joint_names), mid - half, mid + half, vmax, np.broadcast_to(max_acceleration, (n,)))

    def violation(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> dict[str, float]:
        """Largest excess over each limit kind on samples (≤ 0: respected)."""
        return {
            "position": float(max(np.max(self.lower - q), np.max(q - self.upper))),
            "velocity": float(np.max(np.abs(v) - self.velocity)),
            "acceleration": float(np.max(np.abs(a) - self.acceleration)),
        }

    def to_dict(self) -> dict:
        return {
            "joint_names": list(self.joint_names),
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "velocity": self.velocity.tolist(),
            "acceleration": self.acceleration.tolist(),
        }


def robot_limits(robot) -> dict[str, np.ndarray]:
    """The model's own position and velocity limits per joint (±inf where it has none)."""
    lo, hi = robot.position_limits()
    vel = np.asarray(robot.velocity_limits(), dtype=float)
    return {
        "lower": np.where(np.isfinite(lo), lo, -np.inf),
        "upper": np.where(np.isfinite(hi), hi, np.inf),
        "velocity": np.where(vel > 0, vel, np.inf),
    }


def check_sampled_limits(
    traj: Trajectory, limits: ExcitationLimits, hard: dict | None = None, tol: float = 1e-9
) -> dict[str, float]:
    """Verify the samples that will be written, not the optimiser's view of them.

    Checks ``lower ≤ q ≤ upper``, ``|v| ≤ v_max`` and ``|v̇| ≤ a_max`` at every sample of
    ``traj`` against ``hard`` (the robot model's limits, :func:`robot_limits`) and against
    ``limits``. The worst violation beyond ``tol`` raises :class:`ExcitationError` naming the
    joint, sample, time, value and limit; otherwise the largest excess per kind (≤ tol) is returned.
    """
    names = list(traj.joint_names)
    if names != list(limits.joint_names):
        raise ExcitationError(f"trajectory joints {names} do not match the limits' {list(limits.joint_names)}")
    sets = [] if hard is None else [("the robot model's", hard["lower"], hard["upper"], hard["velocity"], None)]
    sets.append(("the excitation", limits.lower, limits.upper, limits.velocity, limits.acceleration))
    excess = {"position": -np.inf, "velocity": -np.inf, "acceleration": -np.inf}
    for source, lo, hi, vmax, amax in sets:
        rows = [("position", "upper limit ", traj.q - hi, traj.q, hi), ("position", "lower limit ", lo - traj.q, traj.q, lo)]
        if traj.v is not None:
            rows.append(("velocity", "limit ±", np.abs(traj.v) - vmax, traj.v, vmax))
        if amax is not None and traj.a is not None:
            rows.append(("acceleration", "limit ±", np.abs(traj.a) - amax, traj.a, amax))
        for kind, what, exc, val, lim in rows:
            if exc.size == 0:
                continue
            exc = np.where(np.isnan(exc), np.inf, exc)
            i, j = np.unravel_index(np.argmax(exc), exc.shape)
            excess[kind] = max(excess[kind], float(exc[i, j]))
            if exc[i, j] > tol:
                raise ExcitationError(
                    f"refusing to write an excitation that leaves {source} limits: joint {names[j]}, sample {i} "
                    f"(t = {traj.t[i]:.6g} s): {kind} {val[i, j]:.6g} beyond the {what}{lim[j]:.6g}"
                )
    return excess


def check_export(rate: float, periods: float, harmonics: int, base_freq: float, max_samples: int = MAX_EXPORT_SAMPLES) -> int:
    """Validate the export options; return the number of samples ``round(periods · rate / f0)``.

    ``rate`` must be finite, above twice the highest harmonic ``H·f0`` (Nyquist) and at
    most :data:`MAX_RATE_HZ`; ``periods`` an integer ≥ 1; the sample count at most ``max_samples``.
    """
    if not (isinstance(rate, (int, float, np.floating, np.integer)) and np.isfinite(rate) and 0 < rate <= MAX_RATE_HZ):
        raise ExcitationError(f"sample rate ({setting('rate')}) must be a finite number in (0, {MAX_RATE_HZ:g}] Hz, got {rate}")
    nyquist = 2.0 * harmonics * base_freq
    if rate <= nyquist:
        raise ExcitationError(
            f"sample rate ({setting('rate')}) {rate:g} Hz must exceed twice the highest harmonic ({harmonics} × {base_freq:g} Hz), "
            f"i.e. > {nyquist:g} Hz"
        )
    if not (np.isfinite(periods) and float(periods).is_integer() and periods >= 1):
        raise ExcitationError(f"periods ({setting('periods')}) must be a whole number ≥ 1, got {periods}")
    n = int(round(periods * rate / base_freq))
    if n > max_samples:
        raise ExcitationError(
            f"the export would hold {n:,} samples ({periods:g} periods × {rate:g} Hz × period {1 / base_freq:g} s; "
            f"{setting('periods')}, {setting('rate')}); "
            f"at most {max_samples:,}"
        )
    return n


@dataclass(frozen=True)
class CartesianBox:
    """Keep the origin of ``frame`` inside a world-frame box at every sample; use ±inf for
    open sides (e.g. ``lower=(-inf, -inf, 0.05)``: at least 5 cm above the z = 0 plane)."""

    frame: str
    lower: tuple[float, float, float] = (-np.inf, -np.inf, -np.inf)
    upper: tuple[float, float, float] = (np.inf, np.inf, np.inf)

    def to_dict(self) -> dict:
        f = lambda v: [None if not np.isfinite(x) else float(x) for x in v]
        return {"frame": self.frame, "lower": f(self.lower), "upper": f(self.upper)}


# ---- random baseline ------------------------------------------------------------------------
def _project_rest(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project (a, b) onto Σ_l a_l = 0, Σ_l ω_l b_l = 0 (zero velocity/acceleration at t = 0)."""
    a = a - a.mean(axis=1, keepdims=True)
    b = b - np.outer(b @ w, w) / (w @ w)
    return a, b


def _fit_to_limits(traj: FourierTrajectory, limits: ExcitationLimits, fill: float) -> FourierTrajectory:
    dq, dv, da = traj.bounds()
    half = 0.5 * (limits.upper - limits.lower)
    with np.errstate(divide="ignore"):
        scale = fill * np.min(np.stack([half / dq, limits.velocity / dv, limits.acceleration / da]), axis=0)
    scale = np.where(np.isfinite(scale), scale, 0.0)
    traj.a = traj.a * scale[:, None]
    traj.b = traj.b * scale[:, None]
    return traj


def random_excitation(
    limits: ExcitationLimits,
    *,
    harmonics: int = 5,
    base_freq: float = 0.1,
    rng: np.random.Generator | int = 0,
    start_at_rest: bool = False,
    fill: float = 1.0,
) -> FourierTrajectory:
    """Random Fourier coefficients (standard normal), centred mid-range and scaled per joint so
    the analytic bounds just fit ``limits`` (``fill`` < 1 leaves a margin) — the scaling of
    :func:`~sensorless.excitation.random_fourier`, for any coordinate set."""
    rng = np.random.default_rng(rng)
    n = len(limits.joint_names)
    w = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
    a, b = rng.normal(size=(n, harmonics)), rng.normal(size=(n, harmonics))
    if start_at_rest:
        a, b = _project_rest(a, b, w)
    q0 = 0.5 * (limits.lower + limits.upper)
    return _fit_to_limits(FourierTrajectory(base_freq, a, b, q0, limits.joint_names), limits, fill)

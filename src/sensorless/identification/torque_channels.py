"""Torque channels checked before a fit: constant, dead while the joint moves, or off in scale.

A channel that carries nothing about its joint (a constant or all-zero column, a sensor that
holds one value while its joint moves) or whose scale is off by more than :data:`SCALE_FACTOR`
from what the prior model predicts on the same samples (N·mm read as N·m, a current without
gains) is fitted without complaint and yields garbage parameters. :class:`TorqueChannels`
accumulates, log by log, what the checks need on the rows of the structure's target (the
torque equations as fitted), and :func:`check_torque_channels` raises a typed error naming the
joint. The scale rule compares root-mean-square values on a subsample of each log:

* too large: ``rms(τ_j) > SCALE_FACTOR · max(rms(τ̂_j), LOADED · max_k rms(τ̂_k))`` (friction on
  a lightly loaded wrist can exceed its own prediction, not a twentieth of the robot's largest
  joint torque by the factor);
* too small: ``rms(τ̂_j) ≥ LOADED · max_k rms(τ̂_k)`` (a joint the prior loads) and
  ``rms(τ_j) < rms(τ̂_j) / SMALL_FACTOR`` (30: friction only adds torque, so a loaded joint
  measuring a thirtieth of its gravity and inertia torque is a unit or gain mistake).

(The large side keeps the factor 100: on a light robot with geared motors, e.g. a simulated
Solo12 at random states, friction and rotor inertia reach 36× a knee's rigid-body torque.)

A prior without mass (``rms(τ̂) ≈ 0`` everywhere) gives no scale, and the rule is skipped.
On the joints the prior loads, the cosine ``cos(τ_j, τ̂_k) = Σ τ_j τ̂_k / √(Σ τ_j² Σ τ̂_k²)`` (gravity
makes it ≈ 1 for k = j on a sound log) also catches a reversed sign (``cos(τ_j, τ̂_j) < −0.5``) and
swapped columns: the assignment of logged to predicted torques that maximises the mean cosine over
the loaded joints (:func:`scipy.optimize.linear_sum_assignment`) is not the identity, reaches 0.9,
and beats the identity's mean by 0.1.

After the compression, :func:`check_information` refuses equations that keep almost nothing of
the logged torques: a contact projection whose rows hold less than :data:`MIN_PROJECTED_ENERGY`
of their energy, ``Σ‖P Sᵀ τ‖² < MIN_PROJECTED_ENERGY · Σ‖τ‖²`` (the contacts constrain every
direction the torques act in: a clamped joint, a robot fixed to the ground), and logs in which
no joint moves at all (one pose: only a few gravity combinations are measured).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..data.trajectory import Trajectory
from ..errors import DataError, UnitsError, setting

__all__ = ["SCALE_FACTOR", "DEAD_SECONDS", "MIN_PROJECTED_ENERGY", "TorqueChannels", "check_information",
           "check_torque_channels"]

SCALE_FACTOR = 100.0
#: a loaded joint whose torque is this many times *below* the prior's is refused (friction only adds torque)
SMALL_FACTOR = 30.0
# a channel holding one exact value for this long (and ≥ DEAD_SAMPLES) while its joint's speed varies is dead
DEAD_SECONDS = 1.0
DEAD_SAMPLES = 100
MIN_PROJECTED_ENERGY = 1e-3
#: a joint the prior loads: rms(τ̂_j) ≥ LOADED · max_k rms(τ̂_k)
LOADED = 0.05
SUBSAMPLE = 2000  # prior torques per log for the scale rule (RNEA on a subsample)
_ANYWAY = f"{setting('check_torques', False)} fits it anyway"
_FIX = f"check the log's torque columns ({setting('columns')}) and units ({setting('gains')} for currents)"


@dataclass
class TorqueChannels:
    """Running statistics of the measured torque rows of ``structure`` over the logs folded so far."""

    structure: object
    rows: tuple[str, ...] = ()
    lo: np.ndarray = field(default=None)  # type: ignore[assignment]
    hi: np.ndarray = field(default=None)  # type: ignore[assignment]
    ss_meas: np.ndarray = field(default=None)  # type: ignore[assignment]
    ss_prior: np.ndarray = field(default=None)  # type: ignore[assignment]
    cross: np.ndarray = field(default=None)  # type: ignore[assignment]  # Σ τ_j τ̂_k
    n_sub: int = 0
    raw_energy: float = 0.0  # Σ‖τ‖² over every logged torque column
    dead: dict = field(default_factory=dict)  # row -> (seconds, source, first time)

    def __post_init__(self) -> None:
        s = self.structure
        joints = set(s.robot.joint_names)
        names = list(s.row_names)
        # the measured rows only: a passive joint's row has the known target 0 (no channel to check);
        # a per-sample map (contacts) mixes the rows, and structures with base rows are not checked
        plain = all(r in joints for r in names) and not s.row_map.per_sample
        act = getattr(s, "actuated_rows", None)
        self._cols = np.asarray(act if act is not None else np.arange(len(names)), dtype=int) if plain \
            else np.zeros(0, dtype=int)
        self.rows = tuple(names[i] for i in self._cols)
        # a contact projection: the logged torques themselves are checked for a constant or zero channel
        # (a joint without actuator logged as zero gets actuator terms: its offset would absorb m·g)
        self._raw = getattr(s, "mode", None) == "projected" and getattr(s.robot, "transmission_matrix", None) is None
        if self._raw:
            self.rows = tuple(s.robot.actuated_joints)
        n = len(self.rows)
        self.lo, self.hi = np.full(n, np.inf), np.full(n, -np.inf)
        self.ss_meas, self.ss_prior = np.zeros(n), np.zeros(n)
        self.cross = np.zeros((n, n))
        self._prior = None

    def add(self, traj: Trajectory) -> Trajectory:
        if traj.tau is not None and len(traj):
            self.raw_energy += float(np.sum(np.square(traj.tau)))
        if not self.rows or traj.tau is None or not len(traj):
            return traj
        if self._raw:
            y = traj.tau[:, [traj.joint_names.index(j) for j in self.rows]]
        else:
            y = self.structure.target(traj)[:, self._cols]
        self.lo = np.minimum(self.lo, y.min(axis=0))
        self.hi = np.maximum(self.hi, y.max(axis=0))
        self._dead_runs(traj, y)
        if self._raw:
            return traj
        sub = traj.take(np.unique(np.linspace(0, len(traj) - 1, min(len(traj), SUBSAMPLE)).astype(int)))
        if self._prior is None:
            self._prior = self.structure.prior()
        with np.errstate(all="ignore"):
            pred = self.structure.torques(self._prior, sub)[:, self._cols]
        ys = self.structure.target(sub)[:, self._cols]
        if np.all(np.isfinite(pred)) and np.all(np.isfinite(ys)):
            self.ss_meas += np.sum(ys**2, axis=0)
            self.ss_prior += np.sum(pred**2, axis=0)
            self.cross += ys.T @ pred
            self.n_sub += len(sub)
        return traj

    def _dead_runs(self, traj: Trajectory, y: np.ndarray) -> None:
        """Longest run of one exact value per row while that joint's speed varies by ≥ 20 % of its peak."""
        if traj.v is None or len(traj) < DEAD_SAMPLES:
            return
        for i, row in enumerate(self.rows):
            if row not in traj.joint_names:
                continue
            v = traj.v[:, traj.joint_names.index(row)]
            peak = float(np.max(np.abs(v)))
            if not peak > 0:
                continue
            same = np.flatnonzero(np.diff(y[:, i]) != 0)  # run boundaries
            starts = np.concatenate(([0], same + 1))
            ends = np.concatenate((same + 1, [len(y)]))
            long = np.flatnonzero(ends - starts >= DEAD_SAMPLES)
            for k in long:
                a, b = starts[k], ends[k]
                secs = float(traj.t[b - 1] - traj.t[a])
                if secs < DEAD_SECONDS or np.ptp(v[a:b]) < 0.2 * peak:
                    continue
                if secs > self.dead.get(row, (0.0,))[0]:
                    self.dead[row] = (secs, traj.source, float(traj.t[a]), float(y[a, i]))


def check_torque_channels(ch: TorqueChannels) -> None:
    """Raise DataError/UnitsError for the first row that is constant, dead while moving, or off in scale."""
    if not ch.rows or not np.all(np.isfinite(ch.hi)):
        return
    for i, row in enumerate(ch.rows):
        span = ch.hi[i] - ch.lo[i]
        if not span > 1e-12 * max(1.0, abs(ch.hi[i]), abs(ch.lo[i])):
            what = "zero" if ch.hi[i] == 0 and ch.lo[i] == 0 else f"constant ({ch.hi[i]:.6g})"
            raise DataError(f"joint '{row}': the torque channel is {what} in every log, so it says nothing "
                            f"about the joint; {_FIX}, lock the joint ({setting('lock_joints', [row])}), or, if it has no "
                            f"actuator (a rail, a free pivot), declare it passive ({setting('passive_joints', [row])}): "
                            "its torque is then known to be 0")
    for row, (secs, src, t0, val) in ch.dead.items():
        raise DataError(f"joint '{row}': the torque channel holds {val:.6g} for {secs:.3g} s from t = {t0:.6g} s "
                        f"while the joint moves (a dead sensor?); {_FIX}, or trim the log ({setting('trim')})", src)
    if ch.n_sub == 0:
        return
    rms_meas = np.sqrt(ch.ss_meas / ch.n_sub)
    rms_prior = np.sqrt(ch.ss_prior / ch.n_sub)
    top = float(np.max(rms_prior))
    if not top > 1e-9:
        return
    for i, row in enumerate(ch.rows):
        big = rms_meas[i] > SCALE_FACTOR * max(rms_prior[i], LOADED * top)
        small = rms_prior[i] >= LOADED * top and rms_meas[i] < rms_prior[i] / SMALL_FACTOR
        if not (big or small):
            continue
        ratio = rms_meas[i] / rms_prior[i] if rms_prior[i] > 0 else np.inf
        raise UnitsError(
            f"joint '{row}': the logged torque (rms {rms_meas[i]:.3g}) is {ratio:.3g}× what the prior model "
            f"predicts on the same samples (rms {rms_prior[i]:.3g}{'' if small else f'; the largest joint: {top:.3g}'}), "
            f"more than {SMALL_FACTOR if small else SCALE_FACTOR:g}× off: a unit or gain mistake? {_FIX}; "
            f"{_ANYWAY}")
    _check_signs_and_order(ch, rms_meas, rms_prior, top)


def check_information(ne, ch: TorqueChannels, motion) -> None:
    """ExcitationError when the equations keep (almost) nothing of the data (module docstring)."""
    from ..errors import ExcitationError

    s = ch.structure
    if getattr(s, "mode", None) == "projected" and ch.raw_energy > 0:
        ratio = float(np.sum(ne.c)) / ch.raw_energy
        if ratio < MIN_PROJECTED_ENERGY:
            frames = ", ".join(getattr(s, "contact_frames", ()) or ())
            raise ExcitationError(
                f"the contact projection keeps {100 * ratio:.2g} % of the logged torques' energy: the contacts "
                f"({frames}) constrain every direction the joint torques act in, so nothing is left to identify "
                "(a clamped or passive joint held by an unmodelled force, a robot fixed to the ground?); check "
                f"{setting('contact_frames')}/{setting('contact_dims')}, or log motion with fewer contacts")
    ranges = motion.ranges if motion is not None and motion.n_samples else {}
    if ranges and all(r < 1e-3 for r in ranges.values()):
        raise ExcitationError(
            f"no joint moves in the {motion.n_samples} samples (every position range < 1e-3): one pose measures "
            "only a few gravity combinations; log a motion (sensorless excite designs one) or several poses")


def _check_signs_and_order(ch: TorqueChannels, rms_meas: np.ndarray, rms_prior: np.ndarray, top: float) -> None:
    """A reversed sign or swapped columns on the joints the prior loads (module docstring)."""
    idx = np.flatnonzero((rms_prior >= LOADED * top) & (rms_meas > 0))
    with np.errstate(all="ignore"):
        cos = (ch.cross / np.sqrt(np.outer(ch.ss_meas, ch.ss_prior)))[np.ix_(idx, idx)]
    # the logged order is an optimal assignment when each joint's own cosine is its row's largest: the
    # assignment (and scipy.optimize's ~0.1 s import) is needed only otherwise
    as_logged = len(idx) < 2 or (np.all(np.isfinite(cos)) and np.all(np.diag(cos) >= cos.max(axis=1)))
    if not as_logged:
        from scipy.optimize import linear_sum_assignment

        r, c = linear_sum_assignment(-cos)
        moved = [(ch.rows[idx[i]], ch.rows[idx[k]]) for i, k in zip(r, c) if i != k]
        best, ident = float(cos[r, c].mean()), float(np.mean(np.diag(cos)))
        if moved and best >= 0.9 and best - ident >= 0.1:
            pairs = ", ".join(f"'{a}' looks like '{b}'" for a, b in moved)
            raise DataError(f"the logged torques match the prior model's torques of other joints (mean cosine "
                            f"{best:.2f} against {ident:.2f} as logged: {pairs}): swapped columns? {_FIX}; "
                            f"{_ANYWAY}")
    for n, i in enumerate(idx):
        if cos[n, n] < -0.5:
            raise DataError(f"joint '{ch.rows[i]}': the logged torque runs against what the prior model predicts "
                            f"(cosine {cos[n, n]:.2f} over the log): a reversed sign convention? {_FIX}; "
                            f"{_ANYWAY}")

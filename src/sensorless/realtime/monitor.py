"""The collision monitor one sample at a time: ``sensorless monitor``'s decisions, causal.

Per sample, with the thresholds a ``sensorless monitor`` run measured on a contact-free window
(:class:`StreamThresholds`, read from its ``monitor.json``):

* rest: joint j is *still* while |v_j| ≤ δ_j, and *settled* once it has been still for the
  observer's settling time T_s; a settled joint's velocity is set to 0 for the observer (at
  rest the friction is the static band, not the sliding law), as offline;
* observer: r = :meth:`~sensorless.estimation.momentum.MomentumObserver.step` (same numbers as
  the offline run on the same samples), raw external torque x = −r on the monitored rows;
* reported torque and contact flag, as :func:`~sensorless.estimation.static_band.classify_at_rest`:
  moving: τ = x − b_m, contact if |x − b_m| > kσ_m; still, or within T_s after a settled rest
  ends (breaking away): contact if |x − c| − f_s > kσ_r (the static-friction dead zone); a
  settled joint reports x − h, h its causal holding level (running mean of x since it settled,
  restarted when x stays more than kσ_r away for T_s, clipped to the band c ± f_s), and while
  breaking away x − the last h. The flag is raised once some joint's crossing has lasted
  ``min_duration`` (the monitor's, 0.02 s by default: a detection delay of that much, and no
  one-sample blips). Before the observer has converged (``warmup_s``) τ and F are NaN and the
  flag is 0;
* force at a frame: F = damped least squares of Jᵀ F = τ (:func:`~sensorless.estimation.force.damped_least_squares`,
  the solver of ``estimate-force`` and ``monitor``), NaN where unobservable.

What the offline monitor decides with hindsight is left out: a still run is known to be a rest
only after T_s (offline, from its start), and contacts closer than ``merge_gap`` are not merged. Dropped samples are not
interpolated: the observer takes the next sample as the following one.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError, OptionError, setting

__all__ = ["RANGES", "StreamMonitor", "StreamThresholds"]


@dataclass(frozen=True)
class StreamThresholds:
    """What the streamed monitor needs from a ``sensorless monitor`` run (per monitored row)."""

    names: tuple[str, ...]
    k: float
    sigma_rest: np.ndarray
    sigma_move: np.ndarray
    bias_move: np.ndarray
    centre: np.ndarray
    band: np.ndarray  # half-width of the dead zone f_s (1 + margin) [N·m]
    rest_speed: np.ndarray  # δ per row [rad/s]; NaN: never at rest
    gain: float
    order: int
    damping: float
    dt: float
    warmup_s: float
    settle_s: float
    min_duration: float = 0.0  # a contact is flagged once its crossing has lasted this long [s]
    source: str = "<thresholds>"
    model: str | None = None

    @classmethod
    def from_doc(cls, doc: dict, source: str = "<thresholds>") -> "StreamThresholds":
        """From a ``monitor.json`` document; DataError naming the file and the missing key."""
        try:
            th, obs, st = doc["thresholds"], doc["observer"], doc["settings"]
            names = tuple(th["names"])
            f = lambda key: np.array([np.nan if x is None else float(x) for x in th[key]])  # noqa: E731
            speeds = st["rest_speed_per_joint"]
            off = st.get("static_friction") == "off"
            rest = np.array([np.nan if off or speeds.get(n) is None else float(speeds[n]) for n in names])
            out = cls(names, float(th["k"]), f("sigma_rest"), f("sigma_moving"), f("bias_moving"), f("band_centre"),
                      f("static_friction"), rest, float(obs["gain"]), int(obs["order"]), float(obs.get("damping", 1.0)),
                      float(obs["dt"]), float(st["warmup_s"]), float(st["settle_s"]), float(st.get("min_duration", 0.0)), source,
                      doc.get("model"))
        except (KeyError, TypeError, ValueError) as e:
            raise DataError(f"{source} is not a monitor.json from `sensorless monitor` ({type(e).__name__}: {e})") from None
        sizes = {len(a) for a in (out.sigma_rest, out.sigma_move, out.bias_move, out.centre, out.band, out.rest_speed)}
        if sizes != {len(names)}:
            raise DataError(f"{source}: inconsistent thresholds ({len(names)} rows, sizes {sorted(sizes)})")
        out.validate()
        return out

    def validate(self) -> None:
        """DataError naming the file and the value when a threshold is outside its range (:data:`RANGES`): a
        tampered ``k = 1e308`` or ``warmup_s = 1e300`` would silently switch detection off."""
        for key, (lo, hi, nan_ok) in RANGES.items():
            vals = np.atleast_1d(np.asarray(getattr(self, key), float))
            for j, x in enumerate(vals):
                if (nan_ok and np.isnan(x)) or (np.isfinite(x) and lo <= x <= hi):
                    continue
                row = f" (row {self.names[j]})" if vals.size > 1 and j < len(self.names) else ""
                raise DataError(f"{self.source}: {key} = {x:.6g}{row} is outside [{lo:g}, {hi:g}]; not a threshold "
                                "file `sensorless monitor` writes: run it again")
        if self.gain * self.dt > 1.0:
            raise DataError(f"{self.source}: observer gain {self.gain:g} 1/s with dt {self.dt:g} s (K·dt > 1) is not "
                            "a stable observer `sensorless monitor` writes: run it again")

    @classmethod
    def read(cls, path: str | Path) -> "StreamThresholds":
        """From ``monitor.json`` or the folder ``sensorless monitor --out`` wrote."""
        from ..io import read_json
        from ..outdir import warn_if_edited

        p = Path(path)
        p = p / "monitor.json" if p.is_dir() else p
        if not (p.exists() or p.is_symlink()):
            raise OptionError(f"{setting('thresholds', str(path))}: no monitor.json there; run `sensorless monitor` on a contact-free "
                              f"log first (its {setting('out')} folder holds the thresholds)")
        doc = read_json(p, "threshold file", error=DataError)
        warn_if_edited(p, "threshold file")
        if not isinstance(doc, dict):
            raise DataError(f"{p} is not a monitor.json from `sensorless monitor` (not a JSON object)")
        return cls.from_doc(doc, str(p))

    @classmethod
    def from_result(cls, mon) -> "StreamThresholds":
        """From a :class:`~sensorless.estimation.monitoring.MonitorResult` (the library route)."""
        th, s = mon.thresholds, mon.settings
        rest = np.full(len(mon.names), np.nan) if s["static_friction"] == "off" else np.asarray(mon.rest_speed, float)
        obs = mon.observer.settings
        return cls(tuple(mon.names), float(th.k), th.sigma_rest.copy(), th.sigma_move.copy(), th.bias_move.copy(),
                   th.centre.copy(), th.band.copy(), rest, float(obs["gain"]), int(obs["order"]),
                   float(obs.get("damping", 1.0)), float(obs["dt"]), float(s["warmup_s"]), float(s["settle_s"]),
                   float(s["min_duration"]), "<MonitorResult>")

    def settings(self) -> dict:
        """The thresholds used, as recorded in the stream summary."""
        f = lambda a: [None if not np.isfinite(x) else float(x) for x in a]  # noqa: E731
        return {"source": self.source, "rows": list(self.names), "k": self.k, "sigma_rest": f(self.sigma_rest),
                "sigma_moving": f(self.sigma_move), "bias_moving": f(self.bias_move), "band_centre": f(self.centre),
                "static_band": f(self.band), "rest_speed": f(self.rest_speed), "gain": self.gain, "order": self.order,
                "dt": self.dt, "warmup_s": self.warmup_s, "settle_s": self.settle_s,
                "min_duration": self.min_duration}


#: field → (lowest, highest, NaN allowed) of a threshold file's values (:meth:`StreamThresholds.validate`)
RANGES = {"k": (1e-3, 100.0, False), "sigma_rest": (0.0, 1e6, False), "sigma_move": (0.0, 1e6, False),
          "bias_move": (-1e6, 1e6, False), "centre": (-1e6, 1e6, False), "band": (0.0, 1e6, False),
          "rest_speed": (0.0, 1e3, True), "gain": (1e-6, 1e6, False), "order": (1, 2, False),
          "damping": (1e-3, 1e3, False), "dt": (1e-6, 1.0, False), "warmup_s": (0.0, 60.0, False),
          "settle_s": (0.0, 60.0, False), "min_duration": (0.0, 10.0, False)}


def streamable(dyn) -> None:
    """OptionError when the model's observer needs more than q, v, τ per sample (module docstring of
    :mod:`.records`): a floating base (base pose and twist) or contact-projected rows (contact flags)."""
    from ..estimation.monitored import monitored_rows

    if getattr(dyn, "floating_base", False):
        raise OptionError("sensorless stream takes fixed-base models: a floating-base robot's observer needs the base "
                          "pose and twist per sample, which the stream record does not carry; use `sensorless monitor`")
    if monitored_rows(dyn)[2]:
        raise OptionError("sensorless stream cannot project by contacts (a model identified with contacts needs the "
                          "contact flags per sample); use `sensorless monitor`")


class StreamMonitor:
    """Per-sample external torque, force at ``frame`` and contact flag (module docstring).

    ``dyn``: :class:`~sensorless.estimation.momentum.MomentumDynamics`; ``th``: its thresholds;
    ``frame``/``reference``: the Cartesian force (None: none). :meth:`step` writes into the
    preallocated ``out`` record (seq, t, τ_ext, F, contact) and returns it (reused every call);
    ``raw`` holds x = −r and ``settled`` the joints whose velocity was set to 0, of the last sample."""

    def __init__(self, dyn, th: StreamThresholds, frame: str | None = None,
                 reference: str = "local_world_aligned") -> None:
        from ..estimation.momentum import MomentumObserver
        from ..estimation.monitored import monitored_rows
        from .guard import SampleGuard
        from .records import RecordLayout

        streamable(dyn)
        names, rows, _ = monitored_rows(dyn)
        if tuple(names) != th.names:
            raise OptionError(f"{setting('thresholds', str(th.source))} monitors rows {list(th.names)}, the model {names}: run "
                              f"`sensorless monitor` with this {setting('model')}")
        self.dyn, self.th, self.rows = dyn, th, np.asarray(rows, int)
        joints = tuple(dyn.names) if dyn.transmission else tuple(dyn.structure.robot.joint_names)
        self.layout = RecordLayout(joints, tuple(dyn.actuated_names), tuple(names), ("fx", "fy", "fz") if frame else ())
        self.cols = np.array([joints.index(n) if n in joints else -1 for n in names])  # row → v index in the record
        speed = np.where(self.cols >= 0, th.rest_speed, np.nan)
        self._speed = np.where(np.isfinite(speed), speed, -1.0)  # |v| ≤ −1 never holds
        self._vcols = np.where(self.cols >= 0, self.cols, 0)
        self.observer = MomentumObserver(dyn, gain=th.gain, order=th.order, damping=th.damping, dt=th.dt)
        self.frame, self.reference = frame, reference
        if frame:  # the frame and reference exist (errors naming them now, not at the first sample)
            from ..estimation.force import REFERENCES

            (dyn.structure.tree if dyn.transmission else dyn.structure.robot).frame_id(frame)
            if reference not in REFERENCES:
                raise OptionError(f"{setting('reference', str(reference))}: choose from {sorted(REFERENCES)}")
            self._force_setup()
        self._thr_rest, self._thr_move = th.k * th.sigma_rest, th.k * th.sigma_move
        # motor coordinates (a transmission) have no limits in the description: the absolute bound only
        self.guard = SampleGuard.for_robot(None if dyn.transmission else dyn.structure.robot, self.layout.joints,
                                           self.layout.actuated)
        self.out = np.zeros(self.layout.n_out)
        self.reset()

    def prime(self) -> None:
        """One throw-away step at q = 0 (clipped into the joint limits), v = τ = 0, then :meth:`reset`: the
        first real sample does not pay for first-call costs (lazy imports, allocations) on top of its latency."""
        lay = self.layout
        q0 = np.clip(np.zeros(len(lay.joints)), self.guard.q_lo, self.guard.q_hi)  # inside the guard's bounds
        self.step(0, 0.0, q0, np.zeros(len(lay.joints)), np.zeros(len(lay.actuated)))
        self.step(1, self.th.warmup_s + self.th.dt, q0, np.zeros(len(lay.joints)),
                  np.zeros(len(lay.actuated)))  # past the warm-up: the force path too
        self.reset()

    def reset(self, counts: bool = True) -> None:
        """Start again: observer state, rest counters and holding levels (and the sample, contact and
        refusal counts unless ``counts`` is False: a sender's restart keeps them)."""
        n = len(self.th.names)
        self.observer.reset()
        self.t0 = None
        self._still_n = np.zeros(n, int)
        self.settled = np.zeros(n, bool)
        self._sum, self._count = np.zeros(n), np.zeros(n, int)
        self._fixed, self._away = np.full(n, np.nan), np.full(n, np.nan)
        self._h, self._h_last = np.full(n, np.nan), np.full(n, np.nan)
        self._leave_until = np.full(n, -np.inf)
        self.raw = np.zeros(n)  # x = −r on the monitored rows, last sample
        self._over_n = 0  # consecutive samples with a crossing
        if counts:
            self.samples = self.contact_samples = 0
            self.rejected, self.last_rejected = 0, None  # samples the guard kept from the observer, and why

    def step(self, seq: float, t: float, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """One sample → the output record ``out`` (module docstring). A sample the guard refuses
        (:mod:`.guard`: non-finite or out of range) never reaches the observer: its record has NaN
        estimates and contact 1, and :attr:`rejected` counts it; at start-up, one that fits as degrees
        or ×1000 torques is a UnitsError."""
        th = self.th
        why = self.guard.check(q, v, tau)
        if why is not None:
            return self._reject(seq, t, q, v, tau, why)
        if self.t0 is None:
            self.t0 = t
        still = np.abs(v[self._vcols]) <= self._speed
        self._still_n = np.where(still, self._still_n + 1, 0)
        was = self.settled
        settled = (self._still_n - 1) * th.dt >= th.settle_s - 1e-9 * th.dt
        ended = was & ~settled
        if ended.any():  # breaking away: report against the last holding level for T_s
            self._leave_until[ended] = t + th.settle_s
            self._h_last[ended] = self._h[ended]
        self.settled = settled
        if settled.any():
            v = v.copy()
            v[self.cols[settled]] = 0.0
        r = self.observer.step(q, v, tau)
        x = -r[self.rows]
        self.raw[:] = x
        tau_rep = x - th.bias_move
        if settled.any():
            self._holding(x, t, settled & ~was, settled)
            tau_rep = np.where(settled, x - self._h, tau_rep)
        breaking = ~still & (t < self._leave_until)
        if breaking.any():
            tau_rep = np.where(breaking, x - self._h_last, tau_rep)
        near = still | breaking
        over = np.where(near, np.abs(x - th.centre) - th.band > self._thr_rest,
                        np.abs(x - th.bias_move) > self._thr_move)
        out, m = self.out, len(self.rows)
        out[0], out[1] = seq, t
        self.samples += 1
        if t - self.t0 < th.warmup_s - 1e-9 * th.dt:  # the observer has not converged: no estimate
            out[2:-1] = np.nan
            out[-1] = 0.0
            return out
        out[2 : 2 + m] = tau_rep
        if self.frame:
            out[2 + m : 5 + m] = self._force(q, tau_rep)
        self._over_n = self._over_n + 1 if over.any() else 0
        flag = self._over_n and (self._over_n - 1) * th.dt >= th.min_duration - 1e-9 * th.dt
        out[-1] = 1.0 if flag else 0.0
        self.contact_samples += flag
        return out

    def _reject(self, seq: float, t: float, q, v, tau, why: str) -> np.ndarray:
        """The record of a refused sample (:meth:`step`)."""
        if self.t0 is None or t - self.t0 < max(self.th.warmup_s, 1.0):
            self.guard.units(q, v, tau)
        self.rejected += 1
        self.last_rejected = f"seq {int(seq)}: {why}"
        out = self.out
        out[0], out[1] = seq, t
        out[2:-1] = np.nan
        out[-1] = 1.0
        return out

    def _holding(self, x: np.ndarray, t: float, start: np.ndarray, settled: np.ndarray) -> None:
        """Causal holding level of the settled joints (``_holding_level`` of :mod:`..estimation.static_band`)."""
        th = self.th
        self._sum[start], self._count[start] = 0.0, 0
        self._fixed[start], self._away[start] = np.nan, np.nan
        for j in np.flatnonzero(settled):
            xi, thr = x[j], self._thr_rest[j]
            fixed, count = self._fixed[j], self._count[j]
            level = fixed if np.isfinite(fixed) else (self._sum[j] / count if count else xi)
            if abs(xi - level) > thr and (np.isfinite(fixed) or count):
                if not np.isfinite(self._away[j]):
                    self._away[j] = t
                if t - self._away[j] >= th.settle_s:
                    self._sum[j], self._count[j], self._fixed[j], self._away[j] = xi, 1, np.nan, np.nan
                    level = xi
            else:
                self._away[j] = np.nan
                if not np.isfinite(fixed):
                    self._sum[j] += xi
                    self._count[j] += 1
                    level = self._sum[j] / self._count[j]
            self._h[j] = np.clip(level, th.centre[j] - th.band[j], th.centre[j] + th.band[j])

    def _force(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """F (3,) at the frame from the reported torque (``cartesian_force`` of one sample)."""
        import pinocchio as pin

        from ..estimation.force import damped_least_squares_one, frame_jacobians

        dyn = self.dyn
        if dyn.transmission:
            st = dyn.structure
            J = frame_jacobians(st.tree, st.tree.full_configuration(st.joint_values(q[None])), self.frame,
                                self.reference)[0, :3] @ st.G
        else:
            qf = self._qf
            qf[self._iq] = q[self._lin]
            if self._cont.size:
                qf[self._iq_c], qf[self._iq_c + 1] = np.cos(q[self._cont]), np.sin(q[self._cont])
            J = pin.computeFrameJacobian(self._model, self._data, qf, self._fid, self._ref)[:3, self.rows]
        return damped_least_squares_one(J, tau)

    def _force_setup(self) -> None:
        """Index maps of ``Robot.full_configuration`` (a fixed base: joints in ``joint_names`` order; a
        continuous joint as cos, sin), the frame and the reference, once."""
        from ..estimation.force import REFERENCES

        if self.dyn.transmission:
            return
        robot = self.dyn.structure.robot
        self._model, self._data = robot.model, robot.model.createData()
        self._fid, self._ref = robot.frame_id(self.frame), REFERENCES[self.reference]
        cont = np.array([robot.is_continuous(n) for n in robot.joint_names], bool)
        iq = np.array([robot.q_index(n) for n in robot.joint_names], int)
        self._lin, self._iq = np.flatnonzero(~cont), iq[~cont]
        self._cont, self._iq_c = np.flatnonzero(cont), iq[cont]
        self._qf = np.zeros(robot.nq)

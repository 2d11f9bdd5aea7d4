"""Scenario plans of the quadruped simulator: base pose, world foot targets and planned
stance flags on the control grid (``wobble``, ``trot``, ``crawl``, ``jump``; :data:`SCENARIOS`).

A scenario is a frozen dataclass of its settings (:class:`Wobble`, :class:`Trot`,
:class:`Crawl`, :class:`Jump`) whose ``plan(ctx, rng) -> Plan`` lays it out; ``rng`` draws its
random choices (amplitudes, frequencies, phases, gait period, jump depth), so a seed fixes it.
The plan's ``settings`` record the settings as used (after any random jitter).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from sensorless.robot import Robot
from .quadruped_profiles import QuadrupedProfile

__all__ = ["SCENARIOS", "Crawl", "Jump", "Plan", "PlanContext", "Trot", "Wobble"]


def _minjerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


def _sines(
    rng: np.random.Generator, t: np.ndarray, amp: float, freq: tuple[float, float], n: int = 2
) -> tuple[np.ndarray, list]:
    """Sum of ``n`` sines with amplitudes amp·U(0.3, 1)/n, frequencies U(freq), random phases."""
    out = np.zeros_like(t)
    comps = []
    for _ in range(n):
        a = amp * rng.uniform(0.3, 1.0) / n
        f = rng.uniform(*freq)
        ph = rng.uniform(0, 2 * np.pi)
        out += a * np.sin(2 * np.pi * f * t + ph)
        comps.append((float(a), float(f), float(ph)))
    return out, comps


@dataclass
class PlanContext:
    """What a scenario plans from: the nominal robot, its profile, the stand posture and the control grid."""

    robot: Robot  # nominal (controller) model
    profile: QuadrupedProfile
    feet_b: np.ndarray  # nominal foot-centre positions in the base frame at the stand posture (F, 3)
    height: float  # standing base height (feet centres at foot_radius)
    t: np.ndarray  # control grid (includes the settle period)
    t0: float  # motion start (= settle)


@dataclass
class Plan:
    """A scenario's references on the control grid: base pose, foot-centre targets and planned stance."""

    base_pos: np.ndarray  # (K, 3) world
    base_rpy: np.ndarray  # (K, 3)
    feet: np.ndarray  # (K, F, 3) world foot-centre targets
    stance: np.ndarray  # (K, F) bool planned stance
    settings: dict[str, Any]
    flights: list[tuple[int, int]] = field(default_factory=list)  # (lift-off index, planned touchdown index)


def _wobble_offsets(rng, t, t0, amp: dict[str, float], freq, ramp: float = 1.0):
    env = _minjerk((t - t0) / ramp) * (t >= t0)
    pos = np.zeros((t.size, 3))
    rpy = np.zeros((t.size, 3))
    comps = {}
    for k, name in enumerate(("x", "y", "z")):
        if amp.get(name, 0.0) > 0:
            s, comps[name] = _sines(rng, t - t0, amp[name], freq)
            pos[:, k] = env * s
    for k, name in enumerate(("roll", "pitch", "yaw")):
        if amp.get(name, 0.0) > 0:
            s, comps[name] = _sines(rng, t - t0, amp[name], freq)
            rpy[:, k] = env * s
    return pos, rpy, comps


_WOBBLE_AMP = {"x": 0.02, "y": 0.02, "z": 0.035, "roll": 0.15, "pitch": 0.15, "yaw": 0.2}


def _settings(scenario, comps: dict, **used) -> dict[str, Any]:
    """The plan's record: the scenario's settings with the values ``used`` (jittered) and the
    random components drawn."""
    return {**asdict(replace(scenario, **used)), "components": comps}


@dataclass(frozen=True)
class Wobble:
    """All four feet fixed; base x, y, height, roll, pitch, yaw follow sums of two sines."""

    amplitude: float = 1.0  # × the default amplitudes (2 cm, 3.5 cm height, 0.15–0.2 rad)
    freq: tuple[float, float] = (0.2, 1.5)  # [Hz], range the sines' frequencies are drawn from

    def plan(self, ctx: PlanContext, rng) -> Plan:
        t = ctx.t
        amp = {k: v * self.amplitude for k, v in _WOBBLE_AMP.items()}
        dpos, rpy, comps = _wobble_offsets(rng, t, ctx.t0, amp, self.freq)
        base = dpos + np.array([0.0, 0.0, ctx.height])
        feet = np.broadcast_to(ctx.feet_b + np.array([0, 0, ctx.height]), (t.size,) + ctx.feet_b.shape).copy()
        stance = np.ones(feet.shape[:2], dtype=bool)
        return Plan(base, rpy, feet, stance, _settings(self, comps, freq=list(self.freq)))


def _stepping_feet(
    ctx: PlanContext,
    base: np.ndarray,
    rpy: np.ndarray,
    swings: list[list[tuple[float, float]]],
    height: float,
    stance_dur: float,
) -> tuple[np.ndarray, np.ndarray]:
    """World foot targets for given swing intervals: footholds under the nominal foot position
    at mid-stance after touchdown, min-jerk horizontally, a smooth bump of ``height``."""
    t = ctx.t
    dt = t[1] - t[0]
    F = ctx.feet_b.shape[0]
    z0 = ctx.profile.foot_radius
    feet = np.empty((t.size, F, 3))
    stance = np.ones((t.size, F), dtype=bool)

    def hold(k: float) -> np.ndarray:
        i = int(np.clip(round((k - t[0]) / dt), 0, t.size - 1))
        c, s = np.cos(rpy[i, 2]), np.sin(rpy[i, 2])
        p = base[i].copy()
        xy = ctx.feet_b[:, :2] @ np.array([[c, s], [-s, c]])
        return np.column_stack([p[0] + xy[:, 0], p[1] + xy[:, 1], np.full(F, z0)])

    start = hold(t[0])
    for f in range(F):
        cur = start[f]
        last = 0
        for lo, td in swings[f]:
            i0 = int(np.searchsorted(t, lo))
            i1 = int(np.searchsorted(t, td))
            if i0 >= t.size:
                break
            feet[last:i0, f] = cur
            nxt = hold(td + 0.5 * stance_dur)[f]
            i1c = min(i1, t.size)
            s = (t[i0:i1c] - lo) / (td - lo)
            m = _minjerk(s)[:, None]
            feet[i0:i1c, f] = cur + (nxt - cur) * m
            feet[i0:i1c, f, 2] += height * 64 * s**3 * (1 - s) ** 3
            stance[i0:i1c, f] = False
            cur, last = nxt, i1c
        feet[last:, f] = cur
    return feet, stance


@dataclass(frozen=True)
class Trot:
    """Diagonal pairs alternate; footholds under the hips at mid-stance; a small base wobble on top."""

    speed: float = 0.25  # [m/s] forward, reached by a min-jerk ramp
    period: float = 0.3  # [s] gait cycle, × U(0.9, 1.1)
    duty: float = 0.55  # stance fraction of the cycle
    swing_height: float = 0.04  # [m] foot lift, × U(0.8, 1.2)
    lateral_speed: float = 0.0  # [m/s]
    yaw_rate: float = 0.0  # [rad/s]
    wobble: float = 0.3  # × the wobble amplitudes (no x, y; half the yaw)
    ramp: float = 1.0  # [s] of the velocity ramp

    def plan(self, ctx: PlanContext, rng) -> Plan:
        t, t0 = ctx.t, ctx.t0
        period = self.period * rng.uniform(0.9, 1.1)
        swing_height = self.swing_height * rng.uniform(0.8, 1.2)
        amp = {k: v * self.wobble for k, v in _WOBBLE_AMP.items() if k not in ("x", "y")}
        amp["yaw"] = amp["yaw"] * 0.5
        dpos, rpy, comps = _wobble_offsets(rng, t, t0, amp, (0.3, 1.2))
        # velocity profile: min-jerk ramp to the commanded speed
        ramp_s = _minjerk((t - t0) / self.ramp)
        dt = t[1] - t[0]
        yaw = np.cumsum(self.yaw_rate * ramp_s) * dt
        vx, vy = self.speed * ramp_s, self.lateral_speed * ramp_s
        c, s = np.cos(yaw), np.sin(yaw)
        base = np.zeros((t.size, 3))
        base[:, 0] = np.cumsum(c * vx - s * vy) * dt
        base[:, 1] = np.cumsum(s * vx + c * vy) * dt
        base[:, 2] = ctx.height
        base += dpos
        rpy[:, 2] += yaw
        stance_dur = self.duty * period
        swing_dur = period - stance_dur
        F = ctx.feet_b.shape[0]
        swings: list[list[tuple[float, float]]] = [[] for _ in range(F)]
        for k, pair in enumerate(ctx.profile.trot_pairs):
            start = t0 + 0.25 + k * 0.5 * period
            while start < t[-1]:
                for f in pair:
                    swings[f].append((start, start + swing_dur))
                start += period
        feet, stance = _stepping_feet(ctx, base, rpy, swings, swing_height, stance_dur)
        return Plan(base, rpy, feet, stance, _settings(self, comps, period=period, swing_height=swing_height))


@dataclass(frozen=True)
class Crawl:
    """Four-beat crawl: per leg (``profile.crawl_order``) a shift, the base moving over the
    support triangle, then a swing."""

    speed: float = 0.05  # [m/s] mean forward speed (one step per leg per period)
    period: float = 3.0  # [s] cycle, × U(0.9, 1.1)
    swing_fraction: float = 0.4  # of each leg's slot spent swinging
    swing_height: float = 0.04  # [m]
    sway: float = 0.6  # how far the base moves to the support triangle's centroid (0–1)
    wobble: float = 0.2  # base wobble scale (0.2: 2 cm height, 0.05 rad roll/pitch, 0.08 rad yaw)

    def plan(self, ctx: PlanContext, rng) -> Plan:
        t, t0 = ctx.t, ctx.t0
        period = self.period * rng.uniform(0.9, 1.1)
        order = ctx.profile.crawl_order
        F = ctx.feet_b.shape[0]
        slot = period / len(order)
        t_swing = slot * self.swing_fraction
        step = self.speed * period
        z0 = ctx.profile.foot_radius
        cur = np.column_stack([ctx.feet_b[:, :2], np.full(F, z0)])
        ts = t0 + 0.25
        base_xy_prev = np.zeros(2)
        events = []  # (shift start, swing start, touchdown, base xy from, base xy to, foot, foothold from, to)
        while ts < t[-1]:
            for f in order:
                others = [g for g in range(F) if g != f]
                centroid = cur[others, :2].mean(axis=0)
                nominal = cur[:, :2].mean(axis=0)
                target = nominal + self.sway * (centroid - nominal)
                new = cur[f].copy()
                new[0] += step
                events.append(
                    (ts, ts + slot - t_swing, ts + slot, base_xy_prev.copy(), target.copy(), f, cur[f].copy(), new.copy())
                )
                cur[f] = new
                base_xy_prev = target
                ts += slot
        base = np.zeros((t.size, 3))
        base[:, 2] = ctx.height
        feet = np.broadcast_to(np.column_stack([ctx.feet_b[:, :2], np.full(F, z0)]), (t.size, F, 3)).copy()
        stance = np.ones((t.size, F), dtype=bool)
        for a, b, c, xy0, xy1, f, p0, p1 in events:
            i0, i1, i2 = np.searchsorted(t, [a, b, c])
            m = _minjerk((t[i0:i1] - a) / (b - a))[:, None]
            base[i0:i1, :2] = xy0 + (xy1 - xy0) * m
            base[i1:, :2] = xy1
            s = (t[i1:i2] - b) / (c - b)
            feet[i1:i2, f] = p0 + (p1 - p0) * _minjerk(s)[:, None]
            feet[i1:i2, f, 2] += self.swing_height * 64 * s**3 * (1 - s) ** 3
            feet[i2:, f] = p1
            stance[i1:i2, f] = False
        amp = {
            "z": 0.02 * self.wobble / 0.2,
            "roll": 0.05 * self.wobble / 0.2,
            "pitch": 0.05 * self.wobble / 0.2,
            "yaw": 0.08 * self.wobble / 0.2,
        }
        dpos, rpy, comps = _wobble_offsets(rng, t, t0, amp, (0.2, 0.8))
        base += dpos
        return Plan(base, rpy, feet, stance, _settings(self, comps, period=period))


@dataclass(frozen=True)
class Jump:
    """Vertical jumps: stand, crouch (min-jerk 0.4 s), push with constant acceleration to the
    take-off height h0 + ``extension``, ballistic flight, constant deceleration landing,
    min-jerk return to h0 (0.5 s), rest; repeated while they fit."""

    crouch: tuple[float, float] = (0.04, 0.07)  # [m] depth, drawn per jump
    push: tuple[float, float] = (5.0, 9.0)  # [m/s²] push acceleration, drawn per jump
    extension: float = 0.035  # [m] above the standing height at take-off
    rest: tuple[float, float] = (0.4, 0.8)  # [s] between jumps, drawn

    def plan(self, ctx: PlanContext, rng) -> Plan:
        t, t0 = ctx.t, ctx.t0
        g = 9.81
        h0 = ctx.height
        z = np.full(t.size, h0)
        stance = np.ones((t.size, ctx.feet_b.shape[0]), dtype=bool)
        flights, jumps = [], []
        ts = t0 + 0.3
        while True:
            dc = rng.uniform(*self.crouch)
            ap = rng.uniform(*self.push)
            hc, hto = h0 - dc, h0 + self.extension
            tp = np.sqrt(2 * (hto - hc) / ap)
            vto = ap * tp
            tf = 2 * vto / g
            hl = hc + 0.02
            ta = 2 * (hto - hl) / vto
            tr = 0.5
            T = 0.4 + tp + tf + ta + tr + rng.uniform(*self.rest)
            if ts + T > t[-1]:
                break
            dec = vto / ta
            # (duration, height z(s) at s seconds into the phase): crouch, push, flight, landing, return
            phases = [
                (0.4, lambda s: h0 + (hc - h0) * _minjerk(s / 0.4)),
                (tp, lambda s: hc + 0.5 * ap * s**2),
                (tf, lambda s: hto + vto * s - 0.5 * g * s**2),
                (ta, lambda s: hto - vto * s + 0.5 * dec * s**2),
                (tr, lambda s: hl + (h0 - hl) * _minjerk(s / tr)),
            ]
            b = ts
            for k, (duration, height) in enumerate(phases):
                a, b = b, b + duration
                m = (t >= a) & (t < b)
                z[m] = height(t[m] - a)
                if k == 2:  # flight
                    stance[m] = False
                    flights.append((int(np.searchsorted(t, a)), int(np.searchsorted(t, b))))
            jumps.append(
                {
                    "crouch": float(dc),
                    "push_acceleration": float(ap),
                    "takeoff_speed": float(vto),
                    "flight_time": float(tf),
                    "start": float(ts - t0),
                }
            )
            ts += T
        base = np.zeros((t.size, 3))
        base[:, 2] = z
        rpy = np.zeros((t.size, 3))
        F = ctx.feet_b.shape[0]
        ground = np.column_stack([ctx.feet_b[:, :2], np.full(F, ctx.profile.foot_radius)])
        feet = np.broadcast_to(ground, (t.size, F, 3)).copy()
        air = ~stance[:, 0]
        # in flight the legs keep the take-off posture (feet fixed relative to the base)
        feet[air] = base[air, None, :] + ctx.feet_b + np.array([0, 0, -self.extension])
        return Plan(base, rpy, feet, stance, {**asdict(self), "jumps": jumps}, flights)


SCENARIOS: dict[str, type] = {"wobble": Wobble, "trot": Trot, "crawl": Crawl, "jump": Jump}

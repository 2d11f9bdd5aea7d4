"""Friction test-bench logs: joints with position and/or velocity and torque (or currents with
drive gains), kept at their own time stamps.

A friction fit needs no uniform sampling (:mod:`sensorless.regressor.friction_state`
integrates its state over position steps), so the samples are never interpolated: a step that is
longer than the others is a step like any other. Only the *derivatives* the log lacks (v from q,
v̇ from v) need a uniform grid: each stretch between two **gaps** (a step over ``max_gap`` median
periods) is differentiated on its own, by the package's Savitzky–Golay filter
(:func:`sensorless.data.prepare`), on a uniform grid when its steps are irregular (the derivatives
are then interpolated back onto the log's stamps). Gaps are reported, never refused; a stretch too
short to differentiate is dropped with a warning. Duplicate stamps are merged (averaged); time going
backwards is an error naming the sample.

Column names: a single-joint CSV may use the bare field words (``t, q, v, tau`` or ``position``,
``velocity``, ``torque``, ``current`` …; :data:`~sensorless.data.tabular.FIELD_WORDS`) — the joint
is then named ``joint`` (or the one name given); multi-joint logs use the usual ``q_<joint>`` …
columns. A log with a velocity but no position gets q = ∫ v dt (trapezoid).

A bench with a drive may log the motor current (``current``) or the input torque (``tau``) *and* the
output torque (``tau_out``, e.g. a jaw-side sensor), and the motor-side position (``q_motor``): they
are kept as they are (``extras``; the friction fit estimates the gain). ``flip`` reverses the sign of
fields a sensor counts the other way (:data:`FLIP_FIELDS`; ``q`` reverses q, v and v̇).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DataError, DataWarning, OptionError, TimestampError, setting
from .trajectory import Trajectory

__all__ = ["DEFAULT_BENCH_GAP", "FLIP_FIELDS", "bare_columns", "read_bench_log"]

#: a step over this many median periods splits the log for differentiation (not an error)
DEFAULT_BENCH_GAP = 10.0
#: fields whose sign ``flip`` may reverse
FLIP_FIELDS = ("q", "tau", "current", "tau_out", "q_motor")


def bare_columns(path: "str | Path") -> "dict | None":
    """The column map of a single-joint CSV whose header uses bare field words (``t, q, v, tau``),
    else None."""
    from .tabular import FIELD_WORDS

    path = Path(path)
    if path.suffix.lower() not in (".csv", ".txt", ".tsv"):
        return None
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            head = next((ln for ln in fh if ln.strip() and not ln.lstrip().startswith("#")), "")
    except OSError:
        return None
    sep = "\t" if "\t" in head else ";" if ";" in head and "," not in head else ","
    names = [c.strip().strip('"') for c in head.strip().split(sep)]
    cols = {}
    for field in ("q", "v", "a", "tau", "current", "tau_out", "q_motor"):
        hit = [n for n in names if n.lower() in FIELD_WORDS[field]]
        if len(hit) == 1:
            cols[field] = hit[0]
    if ("q" not in cols and "v" not in cols) or not {"tau", "current", "tau_out"} & set(cols):
        return None
    if "q" not in cols:
        cols["q"] = cols["v"]  # replaced by ∫ v dt after reading
    return cols


def read_bench_log(path: "str | Path", *, columns: "dict | None" = None, joints: "Sequence[str] | None" = None,
                   gains=None, rate: "float | None" = None, time_unit: "str | None" = None, trim=None,
                   max_gap: float = DEFAULT_BENCH_GAP, velocity: str = "logged",
                   savgol_window: "int | None" = None, need_acceleration: bool = True,
                   flip: Sequence[str] = ()) -> Trajectory:
    """Read a bench log (module docstring) into a Trajectory with t, q, v (and v̇ when
    ``need_acceleration``) and τ at the log's own stamps. ``columns``: a column map (default: the
    file's header conventions, or bare field words); ``joints``: the joint names of a log whose
    columns do not name them; ``velocity``: "logged" (keep a logged v) or "from-q"; ``flip``: fields
    whose sign is reversed (module docstring)."""
    from .trims import trim_window
    from .readers import read_trajectory

    if velocity not in ("logged", "from-q"):
        raise OptionError(f"{setting('velocity')} must be 'logged' or 'from-q', got {velocity!r}")
    if not (np.isfinite(max_gap) and max_gap > 1):
        raise OptionError(f"{setting('max_gap')} must be a number of median periods > 1, got {max_gap!r}")
    src = str(path)
    bare = bare_columns(path) if columns is None else None
    names = list(joints) if joints else None
    if bare is not None:
        if names is not None and len(names) != 1:
            raise DataError(f"the log has one joint (bare columns {sorted(bare.values())}); got {len(names)} joint "
                            "names", src)
        names = names or ["joint"]
    traj = read_trajectory(path, columns=bare or columns, joint_names=names, rate=rate, time_unit=time_unit,
                           gains=gains, allow_duplicate_times=True)
    bad = [f for f in flip if f not in FLIP_FIELDS]
    if bad:
        raise OptionError(f"{setting('flip')} takes fields among {', '.join(FLIP_FIELDS)}, got {bad}")
    drive = "tau_out" in traj.extras and (traj.tau is not None or "current" in traj.extras)
    if traj.tau is None and not drive:
        raise DataError(f"the log has no torque: give a 'tau' column, or currents with {setting('gains')}, or an "
                        f"output torque 'tau_out' with the current", src)
    prov = dict(traj.provenance)
    if flip:
        traj = _flipped(traj, flip, src)
        prov["flipped"] = list(flip)
    if bare is not None and bare["q"] == bare.get("v"):
        traj = traj.with_(q=_integrate(traj.t, traj.v))
        prov["q"] = "derived: ∫ v dt (trapezoid)"
    if trim is not None:
        traj = trim_window(traj, trim)
    traj = _merge_duplicates(traj)
    t = traj.t
    steps = np.diff(t)
    if steps.size == 0:
        raise DataError("the log has fewer than 2 distinct time stamps", src)
    period = float(np.median(steps))
    cuts = np.flatnonzero(steps > max_gap * period) + 1
    prov["bench"] = {"median_period": period, "max_step_periods": float(steps.max() / period),
                     "irregular": bool(np.any(np.abs(steps - period) > 0.05 * period)),
                     "gaps": [[float(t[i - 1]), float(t[i])] for i in cuts[:100]], "n_gaps": int(cuts.size)}
    derive_v = traj.v is None or velocity == "from-q"
    v = None if derive_v else traj.v.copy()
    a = traj.a.copy() if traj.a is not None and not derive_v and savgol_window is None else None
    if derive_v or (need_acceleration and a is None):
        keep = np.ones(len(t), dtype=bool)
        v_new, a_new = np.zeros_like(traj.q), np.zeros_like(traj.q)
        for lo, hi in zip(np.concatenate([[0], cuts]), np.concatenate([cuts, [len(t)]])):
            part = _derivatives(traj.take(slice(lo, hi)), derive_v, savgol_window)
            if part is None:
                keep[lo:hi] = False
                continue
            v_new[lo:hi], a_new[lo:hi] = part
        if not keep.any():
            raise DataError(f"no stretch between gaps (steps over {max_gap:g} median periods) is long enough to "
                            f"differentiate; raise {setting('max_gap')} or log the velocity and acceleration", src)
        if not keep.all():
            warnings.warn(f"{src}: dropped {int((~keep).sum())} sample(s) in stretches between gaps too short to "
                          "differentiate", DataWarning, stacklevel=2)
        v = v_new if derive_v else v
        a = a_new if need_acceleration and a is None else a
        traj = traj.with_(v=v, a=a).take(np.flatnonzero(keep))
        prov["v"] = prov.get("v", "logged") if not derive_v else "derived: d/dt q (Savitzky-Golay per stretch)"
        if need_acceleration:
            prov["a"] = "derived: d/dt v (Savitzky-Golay per stretch)"
    return traj.with_(provenance=prov)


def _flipped(traj: Trajectory, flip: Sequence[str], src: str) -> Trajectory:
    """``traj`` with the sign of the fields ``flip`` reversed (``q``: q, v and v̇)."""
    kw, extras = {}, dict(traj.extras)
    for f in flip:
        if f == "q":
            kw.update({k: -getattr(traj, k) for k in ("q", "v", "a") if getattr(traj, k) is not None})
        elif f == "tau":
            if traj.tau is None:
                raise DataError(f"{setting('flip', 'tau')}: the log has no torque", src)
            kw["tau"] = -traj.tau
        elif f not in extras:
            raise DataError(f"{setting('flip', f)}: the log has no '{f}' column", src)
        else:
            extras[f] = -np.asarray(extras[f], dtype=float)
    return traj.with_(extras=extras, **kw)


def _integrate(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    dq = 0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None]
    return np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(dq, axis=0)])


def _merge_duplicates(traj: Trajectory) -> Trajectory:
    """Samples with the same stamp averaged into one (a stamp going backwards is an error)."""
    d = np.diff(traj.t)
    back = np.flatnonzero(d < 0)
    if back.size:
        i = int(back[0]) + 1
        raise TimestampError(f"time goes backwards at sample {i} (t = {traj.t[i]:.6f} s after {traj.t[i - 1]:.6f} s)",
                             traj.source)
    if not np.any(d == 0):
        return traj
    tu, inv, counts = np.unique(traj.t, return_inverse=True, return_counts=True)

    def avg(x):
        if x is None:
            return None
        out = np.zeros((tu.size,) + x.shape[1:])
        np.add.at(out, inv, x)
        return out / counts.reshape((-1,) + (1,) * (x.ndim - 1))

    extras = {k: (avg(np.asarray(x, dtype=float)) if np.ndim(x) >= 1 and len(x) == traj.t.size else x)
              for k, x in traj.extras.items()}
    return traj.with_(t=tu, q=avg(traj.q), v=avg(traj.v), a=avg(traj.a), tau=avg(traj.tau), extras=extras)


def _derivatives(seg: Trajectory, derive_v: bool, window: "int | None"):
    """(v, v̇) of one stretch between gaps at its own stamps, or None if it is too short."""
    from .filtering import default_savgol_window
    from .prepare import prepare
    from .resample import resample, timing

    t = seg.t
    if len(t) < 12:
        return None
    info = timing(t, seg.source)
    uniform = info.is_uniform()
    grid = seg if uniform else resample(seg, max_gap=max(info.largest_step / info.period, 1.0) + 1.0)
    w = window or default_savgol_window(1.0 / info.period)
    if len(grid) < w + 2:
        return None
    base = grid.with_(a=None, v=None) if derive_v else grid.with_(a=None)
    out = prepare(base, resample="off", rest="off", savgol_window=w, velocity="from-q" if derive_v else "logged")
    if uniform:
        return out.v, out.a
    interp = lambda x: np.column_stack([np.interp(t, out.t, x[:, j]) for j in range(x.shape[1])])  # noqa: E731
    return interp(out.v), interp(out.a)

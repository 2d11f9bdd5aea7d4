"""Logs that are duplicated or corrupted in ways every value check passes.

* The same log given twice (two paths, a symlink, a hard link, a glob through a ``latest -> ..``
  link, or an identical copy: same size and SHA-256) would count its samples twice and shrink the
  uncertainties by up to √copies. :func:`unique_logs` keeps the first of each and warns, naming
  both paths (:func:`duplicate_logs` says which are the same and how).
* Torque rows shuffled against the positions (:func:`shuffled_rows`): on a log whose positions are
  smooth, each moving joint's torque is strongly correlated from one sample to the next (gravity and
  inertia change slowly); shuffled rows leave a lag-1 autocorrelation near 0 on every moving joint.
  Refused when it is below :data:`SHUFFLED_R1` on every joint that moves (at least two, or the only
  one) while the positions' is above :data:`SMOOTH_R1`.
* Periodic zero samples (:func:`periodic_zeros`): a channel exactly 0 on one residue class of the
  sample index modulo k (every other sample, every third, ...), a writer or a bus dropping values,
  while its other samples are not 0. Refused when at least :data:`ZERO_FRACTION` of the samples are
  exact zeros, 90 % of them fall on one residue class and that class is 80 % zeros.

:func:`check_integrity` runs both checks on one log (DataError naming the file, the channel and the
joint). Parquet page checksums are verified by the Parquet readers (:mod:`.tabular`, :mod:`.chunks`).

* A friction bench log (:func:`bench_torque_problem`): the torque of a joint that moves (|v| above 5 % of
  its peak on a fifth of the samples) must vary, and friction dissipates: the mean power τ·v over the
  moving samples is positive. A constant or zero channel, or one whose power is negative (the sign
  flipped), carries no friction law.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from typing import Sequence

import numpy as np

from ..errors import DataError, DataWarning

__all__ = ["SHUFFLED_R1", "SMOOTH_R1", "ZERO_FRACTION", "bench_torque_problem", "check_integrity", "duplicate_logs",
           "periodic_zeros", "shuffled_rows", "unique_logs"]

SHUFFLED_R1 = 0.2
SMOOTH_R1 = 0.99
ZERO_FRACTION = 0.1


def _sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def duplicate_logs(paths: Sequence[str | os.PathLike]) -> list[tuple[int, int, str]]:
    """(index, index of its first occurrence, how) for every path in ``paths`` that is the same log as
    an earlier one: "the same file" (same real path), "a hard link to it" (same inode) or "an identical
    copy" (same size and SHA-256; only files of equal size are hashed). Directories and missing paths
    are left to the readers."""
    seen_real: dict[str, int] = {}
    seen_inode: dict[tuple, int] = {}
    by_size: dict[int, list[int]] = {}
    out: list[tuple[int, int, str]] = []
    stats: dict[int, os.stat_result] = {}
    for i, p in enumerate(paths):
        real = os.path.realpath(os.fspath(p))
        try:
            st = os.stat(real)
        except OSError:
            continue
        if not os.path.isfile(real):
            continue
        if real in seen_real:
            out.append((i, seen_real[real], "the same file"))
            continue
        seen_real[real] = i
        key = (st.st_dev, st.st_ino)
        if key in seen_inode:
            out.append((i, seen_inode[key], "a hard link to it"))
            continue
        seen_inode[key] = i
        stats[i] = st
        by_size.setdefault(st.st_size, []).append(i)
    for group in by_size.values():
        if len(group) < 2:
            continue
        first: dict[str, int] = {}
        for i in group:
            try:
                h = _sha256(os.path.realpath(os.fspath(paths[i])))
            except OSError:
                continue
            if h in first:
                out.append((i, first[h], "an identical copy"))
            else:
                first[h] = i
    return sorted(out)


def unique_logs(paths: Sequence[str | os.PathLike], what: str = "log") -> list:
    """``paths`` with every repeat of a log (:func:`duplicate_logs`) left out, with a DataWarning naming
    each repeat and the path it repeats (the same samples counted twice would shrink the uncertainties)."""
    dups = duplicate_logs(paths)
    if not dups:
        return list(paths)
    drop = {i for i, _, _ in dups}
    shown = "; ".join(f"{paths[i]} is {how} {paths[j]}" for i, j, how in dups[:5])
    more = f" and {len(dups) - 5} more" if len(dups) > 5 else ""
    warnings.warn(f"the same {what} was given more than once ({shown}{more}): each is read once", DataWarning,
                  stacklevel=2)
    return [p for i, p in enumerate(paths) if i not in drop]


def _lag1(x: np.ndarray) -> np.ndarray:
    """Lag-1 autocorrelation of each column of ``x`` (NaN for a constant column)."""
    a, b = x[:-1] - x[:-1].mean(axis=0), x[1:] - x[1:].mean(axis=0)
    den = np.sqrt((a * a).sum(axis=0) * (b * b).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, (a * b).sum(axis=0) / np.where(den > 0, den, 1.0), np.nan)


def shuffled_rows(q: np.ndarray, tau: np.ndarray, names: Sequence[str]) -> str | None:
    """What looks shuffled (module docstring), or None. ``q`` and ``tau`` (samples × joints, the same
    joints: the actuated ones)."""
    if len(q) < 50 or tau.shape != q.shape:
        return None
    rq, rt = _lag1(q), _lag1(tau)
    moving = np.isfinite(rq) & (rq > SMOOTH_R1) & (np.ptp(q, axis=0) > 1e-3) & np.isfinite(rt)
    if not moving.any() or (moving.sum() < 2 and q.shape[1] > 1):
        return None
    if (rt[moving] < SHUFFLED_R1).all():
        shown = ", ".join(f"{names[j]} {rt[j]:.2f}" for j in np.flatnonzero(moving)[:4])
        return (f"the torque rows look shuffled against the positions: on every moving joint the torque's lag-1 "
                f"autocorrelation is below {SHUFFLED_R1} ({shown}) while the positions' is above {SMOOTH_R1}")
    return None


def periodic_zeros(x: np.ndarray, names: Sequence[str], field: str = "tau") -> str | None:
    """The first channel of ``x`` (samples × channels) that is exactly 0 on one residue class of the
    sample index (module docstring), as a message; else None."""
    n = len(x)
    if n < 20:
        return None
    zero = x == 0.0
    frac = zero.mean(axis=0)
    for j in np.flatnonzero((frac >= ZERO_FRACTION) & (frac < 1.0)):
        idx = np.flatnonzero(zero[:, j])
        for k in range(2, 11):
            counts = np.bincount(idx % k, minlength=k)
            r = int(np.argmax(counts))
            if counts[r] >= 0.9 * len(idx) and counts[r] >= 0.8 * len(range(r, n, k)):
                return (f"{field}[{names[j]}] is exactly 0 on every {_nth(k)} sample ({len(idx)} of {n} samples, "
                        f"from row {idx[0]}): values dropped by the logger or the bus, not measurements")
    return None


def _nth(k: int) -> str:
    return {2: "2nd", 3: "3rd"}.get(k, f"{k}th")


def check_integrity(traj, src: str | None = None) -> None:
    """DataError when ``traj`` has shuffled torque rows or periodic zero samples in q, v or τ (module
    docstring); the message names the file, the channel and the joint."""
    src = src or traj.source
    names = list(traj.joint_names)
    for field in ("q", "v", "tau"):
        x = getattr(traj, field, None)
        if x is None:
            continue
        cols = names if np.shape(x)[1] == len(names) else [str(c) for c in range(np.shape(x)[1])]
        why = periodic_zeros(np.asarray(x, float), cols, field)
        if why:
            raise DataError(why, src)
    if traj.tau is not None and np.shape(traj.tau) == np.shape(traj.q):
        why = shuffled_rows(np.asarray(traj.q, float), np.asarray(traj.tau, float), names)
        if why:
            raise DataError(why, src)


def bench_torque_problem(traj) -> str | None:
    """What makes a friction bench log's torque unusable (module docstring), naming the joint; else None."""
    if traj.v is None or traj.tau is None or np.shape(traj.tau) != np.shape(traj.v):
        return None
    v, tau = np.asarray(traj.v, float), np.asarray(traj.tau, float)
    for j, name in enumerate(traj.joint_names):
        peak = np.nanmax(np.abs(v[:, j])) if len(v) else 0.0
        moving = np.abs(v[:, j]) > 0.05 * peak
        if not (peak > 0 and moving.mean() >= 0.2):
            continue
        x = tau[moving, j]
        if np.ptp(x) <= 1e-9 * max(1.0, float(np.max(np.abs(x)))):
            return (f"tau[{name}] is constant ({x[0]:.4g}) while the joint moves: it carries no friction "
                    "(a dead or disconnected channel?)")
        power = float(np.mean(x * v[moving, j]))
        if power < 0:
            return (f"tau[{name}] feeds energy into the motion (mean τ·v = {power:.3g} < 0 while moving): friction "
                    "dissipates, so its sign is flipped (or the velocity's); fix the sign of one")
    return None

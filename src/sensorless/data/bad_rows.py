"""Corrupt rows at the start or end of a log, found (:func:`scan_rows`) and dropped on request
(``skip_bad_rows``, ``--skip-bad-rows``).

Loggers write garbage while they start (uninitialised values, stamps running backwards)
and cut their last row short when killed. A row is corrupt when one of its values is

* not finite (NaN, inf; the missing fields of a CSV row cut short read as NaN), or
* absurd: ``|x| > 1e12``, or ``|x − m| > 1e6 · s`` with m, s the column's median and
  robust scale (:func:`~sensorless.data.outliers.robust_scale` of the finite values);

and a step of the time axis is broken when the time goes backwards, or repeats (unless
repeated stamps are accepted for resampling to merge them; then only a repeat at either
end of the kept rows counts).

**Isolated rows** anywhere: a run of at most :data:`ISOLATED_ROWS` corrupt rows between clean
rows whose stamps continue the clock across it (the step over the run is at most
:data:`ISOLATED_GAP` median periods per row) is a logger's glitch: those rows are dropped, each
named. A row whose stamp breaks the order of its neighbours (``t[i−1] < t[i+1]`` but ``t[i]``
outside them) counts as corrupt there.

The rows kept are then the longest run of clean rows joined by unbroken steps. What lies before
it (the prefix) and after it (the suffix) is dropped when it holds at most
``max(20, 5 % of the rows)`` rows (:func:`max_edge_rows`), as is a first or last row whose
stamp is off the clock: more than :data:`STAMP_GAP` median periods (and a second) from its
neighbour (a logger writing a row at t = 0 before its clock runs: a 3048 s gap otherwise).
A longer piece means the corruption is in the middle of the log: it is not dropped, and the
checks of :func:`~sensorless.data.validate_trajectory` name its sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .outliers import robust_scale

__all__ = ["ABSURD_VALUE", "ABSURD_SCALES", "Edge", "ISOLATED_GAP", "ISOLATED_ROWS", "RowScan", "STAMP_GAP",
           "max_edge_rows", "scan_rows"]

ABSURD_VALUE = 1e12
ABSURD_SCALES = 1e6
EDGE_SHARE = 0.05
MIN_EDGE_ROWS = 20
_SCALE_ROWS = 100_000  # the robust scale of a longer column is taken on evenly spaced rows

ISOLATED_ROWS = 3
ISOLATED_GAP = 3.0
STAMP_GAP = 100.0

_KINDS = ("clean", "missing or non-finite values", "absurd values", "time going backwards", "a repeated time stamp",
          "a stamp off the clock", "a stamp out of order")


def max_edge_rows(n: int) -> int:
    """Most rows a dropped prefix or suffix of an ``n``-row log may hold."""
    return max(MIN_EDGE_ROWS, int(np.ceil(EDGE_SHARE * n)))


@dataclass(frozen=True)
class Edge:
    """Rows ``first..last`` (inclusive) at the ``where`` ("start" | "end") of a log, with why."""

    where: str
    first: int
    last: int
    reasons: tuple[str, ...]

    @property
    def rows(self) -> int:
        return self.last - self.first + 1

    def describe(self) -> str:
        span = f"sample {self.first}" if self.rows == 1 else f"samples {self.first}..{self.last}"
        return f"{self.rows} row(s) at the {self.where} ({span}: {'; '.join(self.reasons)})"

    def to_dict(self) -> dict:
        return {"where": self.where, "first_sample": self.first, "last_sample": self.last, "rows": self.rows,
                "reasons": list(self.reasons)}


@dataclass(frozen=True)
class RowScan:
    """Where the clean rows of an ``n``-row log are (``start:stop``), the corrupt ``edges`` that
    may be dropped, the corruption they do not cover (``middle``: its first sample and why), and
    the time window on the log's stamps that leaves the edges out (``window``, None if none does;
    ``window_loses`` clean rows outside it)."""

    n: int
    start: int
    stop: int
    edges: tuple[Edge, ...]
    middle: str | None
    window: tuple[float, float] | None = None
    window_loses: int = 0
    #: isolated corrupt rows inside ``start:stop`` (module docstring): (row, why)
    isolated: tuple[tuple[int, str], ...] = ()

    @property
    def dropped(self) -> bool:
        return bool(self.edges or self.isolated)

    def keep(self) -> np.ndarray:
        """The rows kept, in order."""
        rows = np.arange(self.start, self.stop)
        return rows[~np.isin(rows, [i for i, _ in self.isolated])] if self.isolated else rows

    def describe(self) -> str:
        iso = [f"{len(self.isolated)} isolated row(s) (" + "; ".join(f"sample {i}: {w}" for i, w in self.isolated) + ")"]
        return " and ".join([e.describe() for e in self.edges] + (iso if self.isolated else []))

    def to_dict(self) -> dict:
        return {"rows_read": self.n, "kept": [self.start, self.stop - 1], "dropped": [e.to_dict() for e in self.edges],
                "isolated": [{"sample": i, "reason": w} for i, w in self.isolated]}


def _row_faults(t: np.ndarray, columns: list) -> tuple[np.ndarray, Callable[[int], str]]:
    """Per row: 0 clean, 1 non-finite, 2 absurd; and a function giving a corrupt row's first bad cell."""
    n = len(t)
    fields = [("t", np.asarray(t, dtype=float)[:, None], ["t"])] + [
        (f, np.asarray(a, dtype=float).reshape(n, -1), labels) for f, a, labels in columns]
    kind = np.zeros(n, dtype=np.int8)
    where = np.zeros((n, 2), dtype=np.int64)  # (field, column) of a corrupt row's first bad cell
    for k, (_, arr, _) in enumerate(fields):
        finite = np.isfinite(arr)
        absurd = finite & (np.abs(arr) > ABSURD_VALUE)
        for c in range(arr.shape[1]):
            x = arr[finite[:, c], c]
            if x.size >= 8:
                m, s = robust_scale(x[:: max(1, x.size // _SCALE_ROWS)][:, None])
                absurd[:, c] |= finite[:, c] & (np.abs(arr[:, c] - m[0]) > ABSURD_SCALES * s[0])
        for code, bad in ((1, ~finite), (2, absurd)):
            rows = np.flatnonzero(bad.any(axis=1) & (kind == 0))
            kind[rows] = code
            where[rows, 0], where[rows, 1] = k, np.argmax(bad[rows], axis=1)

    def cell(i: int) -> str:
        field, arr, labels = fields[where[i, 0]]
        c = where[i, 1]
        name = "'t'" if field == "t" else f"'{field}' column '{labels[c]}'"
        return f"{name} = {arr[i, c]:.3g}"

    return kind, cell


def scan_rows(t: np.ndarray, columns: list, allow_duplicate_times: bool = False) -> RowScan:
    """Scan a log's time axis ``t`` (N,) and signal ``columns`` [(field, (N, k) array, k labels)]
    for corrupt rows (module docstring)."""
    t = np.asarray(t, dtype=float)
    n = len(t)
    kind, cell = _row_faults(t, columns)
    isolated = _isolated(t, kind, cell)
    if isolated:  # scan the rest as if those rows were not there, then map back
        keep = np.setdiff1d(np.arange(n), [i for i, _ in isolated])
        sub = scan_rows(t[keep], [(f, np.asarray(a).reshape(n, -1)[keep], lab) for f, a, lab in columns],
                        allow_duplicate_times)
        edges = tuple(Edge(e.where, int(keep[e.first]), int(keep[e.last]), e.reasons) for e in sub.edges)
        start = int(keep[sub.start]) if sub.start < len(keep) else n
        stop = int(keep[sub.stop - 1]) + 1 if sub.stop > 0 else 0
        inside = tuple((i, w) for i, w in isolated if start <= i < stop)
        return RowScan(n, start, stop, edges, sub.middle, sub.window, sub.window_loses, inside)
    good = kind == 0
    with np.errstate(invalid="ignore"):
        dt = np.diff(t)
    step_ok = (dt >= 0) if allow_duplicate_times else (dt > 0)
    new = np.ones(n, dtype=bool)
    new[1:] = ~(good[:-1] & step_ok)
    seg = np.cumsum(new)
    counts = np.bincount(seg[good], minlength=seg[-1] + 1 if n else 1) if n else np.zeros(1, int)
    if n and counts.max() > 0:
        best = int(np.argmax(counts))
        start = int(np.flatnonzero(good & (seg == best))[0])
        stop = start + int(counts[best])
        while stop - start > 2 and t[start + 1] == t[start]:  # a stamp repeated at the start: the clock not yet running
            start += 1
        while stop - start > 2 and t[stop - 1] == t[stop - 2]:
            stop -= 1
    else:
        start = stop = 0

    def why(i: int, forward: bool) -> tuple[int, str]:
        """Kind and detail of row i; a clean row whose step toward the kept rows is broken is a time fault."""
        if kind[i]:
            return int(kind[i]), cell(i)
        j = i + 1 if forward else i - 1
        if 0 <= j < n:
            a, b = min(i, j), max(i, j)
            if t[b] <= t[a]:
                return (3 if t[b] < t[a] else 4), f"t[{b}] = {t[b]:.6f} s after t[{a}] = {t[a]:.6f} s"
            if t[b] - t[a] > _clock_gap(t):
                return 5, f"t[{a}] = {t[a]:.6f} s, t[{b}] = {t[b]:.6f} s: {t[b] - t[a]:.6g} s apart"
        return 0, ""

    def edge(where: str, rows: range) -> Edge:
        tally: dict[int, list] = {}
        for i in rows:
            k, detail = why(i, where == "start")
            tally.setdefault(k, [0, i, detail])[0] += 1
        reasons = tuple(f"{c} with {_KINDS[k]} ({'first: ' if c > 1 else ''}sample {i}, {d})" if k
                        else f"{c} clean-looking row(s) among them"
                        for k, (c, i, d) in sorted(tally.items(), key=lambda kv: (kv[0] == 0, kv[1][1])))
        return Edge(where, rows.start, rows.stop - 1, reasons)

    start, stop = _off_clock(t, start, stop)
    limit = max_edge_rows(n)
    edges, middle = [], None
    for where, rows, border in (("start", range(0, start), start - 1), ("end", range(stop, n), stop)):
        if not len(rows):
            continue
        if len(rows) <= limit and stop > start:
            edges.append(edge(where, rows))
        elif middle is None:
            k, detail = why(border, where == "start") if 0 <= border < n else (0, "")
            middle = f"sample {border}" + (f" ({_KINDS[k]}: {detail})" if k else "")
    lo_row = start if edges and edges[0].where == "start" else 0
    hi_row = stop if edges and edges[-1].where == "end" else n
    window, loses = _window(t, kind, lo_row, hi_row, start, stop) if edges else (None, 0)
    return RowScan(n, lo_row, hi_row, tuple(edges), middle, window, loses)


def _window(t: np.ndarray, kind: np.ndarray, lo_row: int, hi_row: int, start: int, stop: int):
    """The stamps [lo, hi] of the kept rows ``start:stop`` that no dropped row's plausible stamp
    falls in (a prefix running backwards has stamps after the first kept one), and how many kept rows
    that window loses."""
    core = t[start:stop]
    plausible = np.isfinite(t) & (np.abs(t) <= ABSURD_VALUE)
    head, tail = t[:lo_row][plausible[:lo_row]], t[hi_row:][plausible[hi_row:]]
    lo = core[core > head.max()].min(initial=np.inf) if head.size else core[0]
    hi = core[core < tail.min()].max(initial=-np.inf) if tail.size else core[-1]
    if not lo < hi:
        return None, 0
    return (float(lo), float(hi)), int(np.sum((core < lo) | (core > hi)))


def _clock_gap(t: np.ndarray) -> float:
    """A step longer than this [s] between a first or last row and its neighbour is a stamp off the clock."""
    with np.errstate(invalid="ignore"):
        dt = np.diff(t)
    dt = dt[np.isfinite(dt) & (dt > 0)]
    return max(STAMP_GAP * float(np.median(dt)), 1.0) if dt.size else np.inf


def _off_clock(t: np.ndarray, start: int, stop: int) -> tuple[int, int]:
    """The kept run ``start:stop`` without a first or last row whose stamp is off the clock (module docstring)."""
    gap = _clock_gap(t)
    while stop - start > 2 and t[start + 1] - t[start] > gap:
        start += 1
    while stop - start > 2 and t[stop - 1] - t[stop - 2] > gap:
        stop -= 1
    return start, stop


def _isolated(t: np.ndarray, kind: np.ndarray, cell) -> list[tuple[int, str]]:
    """Runs of at most ``ISOLATED_ROWS`` corrupt rows between clean rows whose stamps continue the clock across
    them (module docstring), each row with why."""
    n = len(t)
    if n < 8:
        return []
    bad = kind != 0
    order = np.zeros(n, bool)  # a stamp outside its neighbours while they are in order
    with np.errstate(invalid="ignore"):
        inner = (t[2:] > t[:-2]) & ((t[1:-1] < t[:-2]) | (t[1:-1] > t[2:]))  # a repeat is not out of order
    order[1:-1] = inner & ~bad[1:-1] & ~bad[:-2] & ~bad[2:]
    bad = bad | order
    with np.errstate(invalid="ignore"):
        dt = np.diff(t)
    fine = dt[np.isfinite(dt) & (dt > 0)]
    period = float(np.median(fine)) if fine.size else np.nan
    out = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], bad.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):  # corrupt rows a..b-1
        if a == 0 or b == n or b - a > ISOLATED_ROWS:
            continue
        step = t[b] - t[a - 1]
        if not (np.isfinite(step) and 0 < step <= ISOLATED_GAP * (b - a + 1) * period):
            continue
        for i in range(a, b):
            why = (f"{_KINDS[kind[i]]}, {cell(i)}" if kind[i] else
                   f"{_KINDS[6]}, t = {t[i]:.6f} s between {t[i - 1]:.6f} and {t[i + 1]:.6f} s")
            out.append((int(i), why))
    return out

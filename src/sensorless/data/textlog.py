"""A folder of per-signal text files, joined on their time column, read into a
:class:`~sensorless.data.names.RawLog`.

Controllers often write one whitespace text file per signal: ``run/q.dat``, ``run/dq.dat``,
``run/tau.dat`` (``.dat``, ``.txt``, ``.log`` or ``.csv``), each a time or tick column and
one column per joint. ``--data run/`` reads the folder as one log:

* each file stands for the field its name is recognised as
  (:data:`~sensorless.data.names.FIELD_NAMES`: ``q``, ``dq``/``v``, ``ddq``, ``tau``/
  ``effort``, ``current``/``i``, ...); ``--columns 'q=pos;tau=trq'`` names the files instead
  (by stem or file name). A field may also be composed of columns of several files, joint
  columns in the order given: ``--columns 'q=height_sensors.dat:1,joint_positions.dat:1:3'``
  (``FILE:K`` is the file's column K, ``FILE:A:B`` its columns A..B−1, counted from 0 with the
  time column; a passive slider whose position another sensor logs). Contact flags (and
  wrenches) come from a file the same way, ``--columns 'contact=feet.dat'``. Files no field uses are
  named in one warning;
* the time column of each file is the one a header names (``t``, ``time``, ``tick``, ...,
  or ``--columns t=NAME``); without a header it is the first column. Every other column is
  a joint, in the same order in every file (a header shared by every file gives the joint names);
* the files are joined on the stamps they all have (an inner join on exact values: ticks
  are integers); rows only some files have are dropped with a warning, and files that share
  fewer than half of their stamps are refused.

The stamps' unit is then read as any time column's (:mod:`.timebase`: ticks need
``--time-unit tick --rate HZ``).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError, DataWarning, ShapeMismatchError, TimestampError, setting, did_you_mean
from .limits import prescan_text
from .arrays import EXTRA_KEYS
from .names import FIELD_NAMES, RawLog, field_of, normalise, pick_key, short_list
from .tabular import TIME_COLUMNS, numeric_columns, read_text_table

__all__ = ["read_signal_folder", "SIGNAL_SUFFIXES"]

SIGNAL_SUFFIXES = (".dat", ".txt", ".log", ".csv")
#: a join that keeps less than this share of some file's rows means the files do not share stamps
MIN_JOINED_SHARE = 0.5


def _files(path: Path, src: str) -> dict[str, Path]:
    files = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in SIGNAL_SUFFIXES
                   and not p.name.startswith("."))
    if not files:
        raise DataError(f"a folder log holds one text file per signal ({', '.join(SIGNAL_SUFFIXES)}: q.dat, "
                        f"tau.dat, ...); this folder has none", src)
    by_stem: dict[str, Path] = {}
    for f in files:
        if f.stem in by_stem:
            raise DataError(f"two files for one signal: {by_stem[f.stem].name} and {f.name}; keep one", src)
        by_stem[f.stem] = f
    return by_stem


def _pieces(fld: str, spec: str, files: dict[str, Path], src: str) -> list[tuple[Path, "tuple[int, int] | None"]]:
    """``'a.dat:1,b.dat:1:3'`` -> [(a.dat, (1, 2)), (b.dat, (1, 3))]; ``'a'`` -> [(a.dat, None)] (every joint column)."""
    out = []
    for item in spec.split(","):
        name, *sel = (s.strip() for s in item.strip().split(":"))
        hit = next((f for f in files.values() if name in (f.name, f.stem)), None)
        if hit is None:
            raise DataError(f"no file '{name}' (for '{fld}') in the folder; files: {short_list(list(files))}", src)
        try:
            cols = None if not sel else (int(sel[0]), int(sel[0]) + 1) if len(sel) == 1 else (int(sel[0]), int(sel[1]))
        except ValueError:
            cols = (-1, -1)
        if cols is not None and (len(sel) > 2 or not 0 <= cols[0] < cols[1]):
            raise DataError(f"{setting('columns', {fld: spec})}: '{item.strip()}' is not FILE, FILE:K or FILE:A:B "
                            "(0-based column numbers of the file, A < B)", src)
        out.append((hit, cols))
    return out


def _choose(files: dict[str, Path], columns: Mapping | None, src: str) -> dict[str, list]:
    """field -> [(file, columns or None)]: the ``columns`` entries (a stem or file name, or pieces of files),
    else the recognised names."""
    chosen: dict[str, list] = {}
    stems = list(files)
    for fld in (*FIELD_NAMES, *EXTRA_KEYS):
        if fld == "t":
            continue
        if columns is not None and fld in columns:
            spec = columns[fld]
            if not isinstance(spec, str):
                raise DataError(f"{setting('columns', {fld: '...'})} must name one file of the folder, or columns of "
                                f"files ({setting('columns', {fld: 'a.dat:1,b.dat:1:3'})}), got {spec!r}", src)
            chosen[fld] = _pieces(fld, spec, files, src)
        elif fld in FIELD_NAMES and (stem := pick_key(fld, stems, None, src)) is not None:
            chosen[fld] = [(files[stem], None)]
    if "q" not in chosen:
        raise DataError(f"no file of joint positions (looked for {[n + '.dat' for n in FIELD_NAMES['q'][:4]]}...); "
                        f"files: {short_list(stems)}; name it with {setting('columns', {'q': 'FILE'})}", src)
    return chosen


def _time_label(df, header: bool, columns: Mapping | None, name: str):
    if columns is not None and "t" in columns:
        want = str(columns["t"]).strip()
        for c in df.columns:
            if str(c) == want or (not header and want.isdigit() and c == int(want)):
                return c
        raise DataError(f"no time column '{want}' ({setting('columns', {'t': '...'})}); "
                        f"{_close(want, list(map(str, df.columns)))}columns: {short_list(list(df.columns))}", name)
    if not header:
        return df.columns[0]
    lower = {normalise(c): c for c in df.columns}
    return next((lower[normalise(n)] for n in TIME_COLUMNS if normalise(n) in lower), None)


def _read_one(path: Path, fld: str, columns: Mapping | None, cols: "tuple[int, int] | None" = None):
    """(time or None, values (N, n), the time column's label, joint header or None) of one file; ``cols``: the
    file's columns [A, B) to take (default every column but the time)."""
    name = str(path)
    prescan_text(path, name)
    df, header = read_text_table(path)
    tcol = _time_label(df, header, columns, name)
    joints = [c for c in df.columns if c != tcol]
    if cols is not None:
        if cols[1] > len(df.columns):
            raise DataError(f"columns {cols[0]}:{cols[1]} (for '{fld}') are beyond the file's {len(df.columns)} "
                            "columns (counted from 0 with the time column)", name)
        joints = list(df.columns[cols[0]:cols[1]])
        if tcol in joints:
            raise DataError(f"columns {cols[0]}:{cols[1]} (for '{fld}') include the time column '{tcol}'", name)
    if not joints:
        raise DataError(f"no joint columns besides the time column '{tcol}'", name)
    t = None if tcol is None else numeric_columns(df, [tcol], "t", name)[:, 0]
    values = numeric_columns(df, joints, fld, name)
    label = None if tcol is None else (str(tcol) if header else f"column {tcol}")
    return t, values, label, [str(c) for c in joints] if header else None


def _join(parts: dict[str, tuple], src: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Rows at the stamps every file has (module docstring)."""
    for fld, (path, t, _) in parts.items():
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise TimestampError(f"time column of {path.name} has a non-finite value at row {bad[0]}", src)
        rep = np.flatnonzero(np.diff(t) <= 0)
        if rep.size:
            raise TimestampError(f"time column of {path.name} does not increase at row {rep[0] + 1} "
                                 f"({t[rep[0]]:.10g} then {t[rep[0] + 1]:.10g})", src)
    common = None
    for _, t, _ in parts.values():
        common = t if common is None else np.intersect1d(common, t, assume_unique=True)
    dropped = []
    out: dict[str, np.ndarray] = {}
    for fld, (path, t, values) in parts.items():
        keep = np.isin(t, common, assume_unique=True)
        if keep.sum() < max(2, MIN_JOINED_SHARE * len(t)):
            spans = "; ".join(f"{p.name}: {len(tt)} rows, {tt[0]:.10g}..{tt[-1]:.10g}" for p, tt, _ in parts.values())
            raise TimestampError(f"the signal files do not share their time stamps (joined on exact values, "
                                 f"{len(common)} in common) — {spans}", src)
        if not keep.all():
            dropped.append(f"{int((~keep).sum())} of {path.name}")
        out[fld] = values[keep]
    if dropped:
        warnings.warn(f"{src}: joined the signal files on their time column: dropped the rows not in every file "
                      f"({', '.join(dropped)}); {len(common)} samples remain", DataWarning, stacklevel=4)
    return common, out


def read_signal_folder(path: Path, columns: Mapping | None) -> RawLog:
    src = str(path)
    files = _files(path, src)
    chosen = _choose(files, columns, src)
    read = _compose({fld: [(f, *_read_one(f, fld, columns, cols)) for f, cols in pieces]
                     for fld, pieces in chosen.items()}, src)
    timed = [fld for fld, r in read.items() if r[1] is not None]
    if timed and len(timed) != len(read):
        untimed = [read[f][0].name for f in read if f not in timed]
        raise DataError(f"{', '.join(untimed)} ha(s) no time column while {read[timed[0]][0].name} has one; "
                        "every signal file needs the same time/tick column", src)
    n = read["q"][2].shape[1]
    wrong = [f"{r[0].name} ({r[2].shape[1]})" for fld, r in read.items() if fld != "q" and r[2].shape[1] != n
             and fld in ("v", "a", "tau", "current", "command", "tau_out", "q_motor")]
    if wrong:
        raise ShapeMismatchError(f"{read['q'][0].name} has {n} joint columns but {', '.join(wrong)}", src)
    if timed:
        t, arrays = _join({fld: (r[0], r[1], r[2]) for fld, r in read.items()}, src)
        arrays["t"] = t
    else:
        lengths = {r[0].name: len(r[2]) for r in read.values()}
        if len(set(lengths.values())) > 1:
            raise ShapeMismatchError(f"the signal files have no time column and different lengths {lengths}", src)
        arrays = {fld: r[2] for fld, r in read.items()}
    headers = [r[4] for fld, r in read.items() if fld not in EXTRA_KEYS]
    names = headers[0] if headers[0] is not None and all(h == headers[0] for h in headers) else None
    origin = {fld: columns[fld] if columns is not None and fld in columns else r[0].name for fld, r in read.items()}
    if timed:
        origin["t"] = read["q"][3]
    used = {f.stem for pieces in chosen.values() for f, _ in pieces}
    unused = [f.name for stem, f in files.items() if stem not in used]
    if names is not None and any(field_of(n) is not None for n in names):
        names = None  # a header of field words (q1?) is not joint names
    extras = {k: arrays.pop(k) for k in EXTRA_KEYS if k in arrays}
    return RawLog(arrays, names, origin, extras, unused)


def _compose(read: dict[str, list[tuple]], src: str) -> dict[str, tuple]:
    """One (path, t, values, time label, header) per field from its pieces: the pieces joined on the stamps they
    share (as the files of different fields are) and their columns side by side, in the order given."""
    out = {}
    for fld, pieces in read.items():
        if len(pieces) == 1:
            out[fld] = pieces[0]
            continue
        if any(p[1] is None for p in pieces):
            if not all(p[1] is None for p in pieces) or len({len(p[2]) for p in pieces}) > 1:
                raise DataError(f"the files composing '{fld}' ({', '.join(p[0].name for p in pieces)}) need the same "
                                "time column, or none and the same length", src)
            values = np.hstack([p[2] for p in pieces])
            out[fld] = (pieces[0][0], None, values, None, None)
            continue
        t, parts = _join({str(i): (p[0], p[1], p[2]) for i, p in enumerate(pieces)}, src)
        heads = [p[4] for p in pieces]
        header = sum(heads, []) if all(h is not None for h in heads) else None
        out[fld] = (pieces[0][0], t, np.hstack([parts[str(i)] for i in range(len(pieces))]), pieces[0][3], header)
    return out


def _close(name: str, known) -> str:
    hint = did_you_mean(name, known)
    return f"{hint} " if hint else ""

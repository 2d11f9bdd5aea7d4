"""Time windows cut out of logs: one window (:class:`TrimWindow`) and the windows of a
command's logs (:class:`LogTrims`: one for every log, ``NAME=WINDOW`` for one log).

A window is ``"START:END"`` seconds after the log's first sample (a negative number counts
back from its last sample; either end may be left open, ``":49.6"``), or ``"abs:T0:T1"``
on the log's own stamps. Readers cut it before they check the time axis
(:func:`~sensorless.data.validate_trajectory`), so a window can leave a corrupt prefix out.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from ..errors import DataError, OptionError, TimestampError, TooFewSamplesError, setting
from .trajectory import Trajectory

__all__ = ["TrimWindow", "trim_window", "LogTrims"]


@dataclass(frozen=True)
class TrimWindow:
    """A time window ``[start, end]`` [s]; ``None`` is an open end.

    Relative (default): seconds after the first sample, a negative value counts back
    from the last sample (``-2`` = 2 s before the end). ``absolute``: the log's stamps.
    """

    start: float | None = None
    end: float | None = None
    absolute: bool = False

    @classmethod
    def parse(cls, spec: "str | tuple | TrimWindow") -> "TrimWindow":
        """``"1.9:49.6"``, ``":49.6"``, ``"1.9:"``, ``"2:-1.5"``, ``"abs:1712.3:1760"``, or ``(start, end)``."""
        if isinstance(spec, TrimWindow):
            return spec
        if isinstance(spec, (tuple, list)):
            if len(spec) != 2:
                raise DataError(f"trim window must be (start, end), got {spec!r}")
            return cls(*(None if v is None else _seconds(v, spec) for v in spec))
        if not isinstance(spec, str):
            raise DataError(f"trim window must be 'START:END' or (start, end), got {spec!r}")
        text = spec.strip()
        absolute = text.lower().startswith("abs:")
        body = text[4:] if absolute else text
        parts = body.split(":")
        if len(parts) != 2:
            raise DataError(f"trim window '{spec}' is not START:END seconds (e.g. '1.9:49.6', ':49.6', 'abs:100:160')")
        start, end = (None if not p.strip() else _seconds(p, spec) for p in parts)
        return cls(start, end, absolute)

    def bounds(self, t: np.ndarray) -> tuple[float, float]:
        """Absolute ``(lo, hi)`` on the time axis ``t``."""
        t0, t1 = float(t[0]), float(t[-1])

        def at(v: float | None, open_end: float) -> float:
            if v is None:
                return open_end
            if self.absolute:
                return v
            return t0 + v if v >= 0 else t1 + v

        return at(self.start, -np.inf), at(self.end, np.inf)

    def __str__(self) -> str:
        fmt = lambda v: "" if v is None else f"{v:g}"  # noqa: E731
        return ("abs:" if self.absolute else "") + f"{fmt(self.start)}:{fmt(self.end)}"


def _seconds(text: Any, spec: Any) -> float:
    try:
        val = float(text)
    except (TypeError, ValueError):
        raise DataError(f"trim window {spec!r}: {text!r} is not a number of seconds") from None
    if not np.isfinite(val):
        raise DataError(f"trim window {spec!r}: {text!r} is not a finite number of seconds")
    return val


def trim_window(traj: Trajectory, window: "str | tuple | TrimWindow") -> Trajectory:
    """Samples of ``traj`` whose stamps lie inside ``window`` (typed errors if it is empty or outside the log).

    The log need not be validated yet: stamps that are not finite or run backwards before the
    first kept sample or after the last are dropped by the same test (a corrupt prefix or
    suffix), but such rows amid the kept ones are a TimestampError naming the first of them.
    A relative window counts from the first and last sample, so those two stamps must be finite."""
    src = traj.source
    try:
        win = TrimWindow.parse(window)
    except DataError as exc:
        raise type(exc)(str(exc), src) from None
    t = np.asarray(traj.t, dtype=float)
    if not win.absolute and not (np.isfinite(t[0]) and np.isfinite(t[-1])):
        raise DataError(f"trim window '{win}' counts from the first/last sample, whose stamp is not finite "
                        f"({t[0]:.6g} .. {t[-1]:.6g}); drop corrupt rows at the ends with "
                        f"{setting('skip_bad_rows', True)}, or give the log's own stamps: {setting('trim', 'abs:T0:T1')}",
                        src)
    lo, hi = win.bounds(t)
    first, last = float(np.nanmin(t)), float(np.nanmax(t))
    span = f"the log spans {first:.6g}..{last:.6g} s ({last - first:.3f} s)"
    if lo >= hi:
        raise DataError(f"trim window '{win}' is empty: start {lo:.6g} s is not before end {hi:.6g} s; {span}", src)
    if lo > last or hi < first:
        raise DataError(f"trim window '{win}' = [{lo:.6g}, {hi:.6g}] s lies outside the log: {span}", src)
    keep = (t >= lo) & (t <= hi)
    n = int(keep.sum())
    if n < 2:
        raise TooFewSamplesError(f"trim window '{win}' = [{lo:.6g}, {hi:.6g}] s holds {n} sample(s); {span}", src)
    inside = np.flatnonzero(keep)
    hole = np.flatnonzero(~keep[inside[0]:inside[-1] + 1]) + inside[0]
    if hole.size:  # rows amid the window whose stamps lie outside it: corrupt stamps, not a cut
        k = int(hole[0])
        raise TimestampError(
            f"trim window '{win}' = [{lo:.6g}, {hi:.6g}] s would leave out {hole.size} sample(s) amid the ones it "
            f"keeps, first sample {k} (t[{k}] = {t[k]:.6g} s after t[{k - 1}] = {t[k - 1]:.6g} s): stamps that are "
            "not finite or run backwards in the middle of the log are corruption, not a window; fix the log's time "
            "column, or choose a window that ends before that sample", src)
    out = traj.take(keep)
    note = f"trim({win})"
    units = {**out.units, "processing": "; ".join(p for p in (out.units.get("processing"), note) if p)}
    return out.with_(units=units, provenance={**out.provenance, "trim": {
        "window": str(win), "t_start": float(out.t[0]), "t_end": float(out.t[-1]), "samples": n}})


def _parts(path: "str | os.PathLike") -> tuple[str, ...]:
    return Path(os.path.normpath(str(path))).parts


@dataclass(frozen=True)
class LogTrims:
    """The trim windows of a run (setting `` `trim` ``; the CLI's ``--trim``): ``default`` cuts every
    log, ``named`` entries ``(NAME, window)`` one log each (NAME: the log's path as given, a trailing
    part of it, or its file name), winning over ``default``."""

    default: TrimWindow | None = None
    named: tuple[tuple[str, TrimWindow], ...] = ()

    @classmethod
    def parse(cls, values: "str | TrimWindow | Sequence[str] | LogTrims | None", option: str = setting("trim")) -> "LogTrims":
        """``None``, one window, or a list of ``WINDOW`` (at most one) and ``NAME=WINDOW`` items."""
        if isinstance(values, LogTrims):
            return values
        if values is None:
            return cls()
        if isinstance(values, (str, TrimWindow, tuple)):
            values = [values]
        default, named = None, []
        for v in values:
            if isinstance(v, str) and "=" in v:
                name, _, spec = v.rpartition("=")
                if not name.strip():
                    raise OptionError(f"{option} '{v}': no log name before '='; give FILE=START:END")
                named.append((name.strip(), _window(spec, option, v)))
            elif default is not None:
                raise OptionError(f"{option} gives two windows for every log ('{default}' and '{v}'); give one, "
                                  "and FILE=START:END for a window of one log")
            else:
                default = _window(v, option, v)
        return cls(default, tuple(named))

    def _matches(self, name: str, path: "str | os.PathLike") -> bool:
        if str(path) == name or os.path.basename(os.path.normpath(str(path))) == name:
            return True
        want, have = _parts(name), _parts(path)
        if want and have[-len(want):] == want:
            return True
        try:
            return os.path.exists(name) and os.path.samefile(name, str(path))
        except OSError:
            return False

    def window_for(self, path: "str | os.PathLike") -> TrimWindow | None:
        """The window of the log at ``path``: its own NAME=WINDOW, else the default."""
        own = [w for n, w in self.named if self._matches(n, path)]
        return own[0] if own else self.default

    def check(self, paths: Iterable["str | os.PathLike"], option: str = setting("trim")) -> None:
        """OptionError for a NAME that matches none of ``paths``, several different files, or a
        log that two NAMEs match."""
        paths = [str(p) for p in paths]
        by_log: dict[str, str] = {}
        for name, _ in self.named:
            hits = [p for p in paths if self._matches(name, p)]
            if not hits:
                raise OptionError(f"{option} {name}=...: '{name}' matches none of the logs ({', '.join(paths)}); "
                                  "name a log by its path or file name")
            files = {os.path.realpath(p) for p in hits}
            if len(files) > 1:
                raise OptionError(f"{option} {name}=...: '{name}' is ambiguous, it matches {', '.join(sorted(set(hits)))}; "
                                  "give more of the path")
            for p in hits:
                if by_log.get(p, name) != name:
                    raise OptionError(f"{option}: log {p} is named twice ('{by_log[p]}' and '{name}'); give it one window")
                by_log[p] = name

    def resolve(self, paths: Sequence["str | os.PathLike"], option: str = setting("trim")) -> list[TrimWindow | None]:
        """One window (or None) per path, after :meth:`check`."""
        self.check(paths, option)
        return [self.window_for(p) for p in paths]

    def settings(self, paths: Sequence["str | os.PathLike"]) -> dict:
        """``{"trim": default window or None, "trims": {path: window or None}}`` (settings of a run)."""
        return {"trim": None if self.default is None else str(self.default),
                "trims": {str(p): (None if w is None else str(w)) for p, w in zip(paths, self.resolve(paths))}}

    def __bool__(self) -> bool:
        return self.default is not None or bool(self.named)


def _window(spec: Any, option: str, given: Any) -> TrimWindow:
    try:
        return TrimWindow.parse(spec)
    except DataError as exc:
        raise OptionError(f"{option} '{given}': {exc}") from None

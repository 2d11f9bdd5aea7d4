"""The unit of a log's time column, and its conversion to seconds.

``time_unit`` is one of :data:`TIME_UNITS`: ``s``, ``ms``, ``us``, ``ns``, or ``tick``
(a controller's cycle counter: t = tick / rate, ``rate`` being the tick rate in Hz;
command line ``--time-unit tick --rate 1000``). Without a unit:

* Unix-epoch stamps in ms, µs or ns (ROS's ``%time``) are told apart by magnitude (seconds
  since 1970 stay below 1e11 until the year 5138) and converted;
* a column named like a tick counter (:data:`~sensorless.data.names.TICK_NAMES`), or one that
  counts in whole steps of at least 1 (read as seconds: a log of at most 1 Hz, which no
  dynamics log is), is refused with the flag to give instead of being read as seconds;
* relative stamps whose median step is over a second are refused the same way.
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError, UnitsError, setting
from .names import is_tick_name

__all__ = ["TIME_UNITS", "TIME_SCALE", "MIN_RATE", "MAX_RATE", "to_seconds", "check_time_unit", "check_rate"]

TIME_UNITS = ("s", "ms", "us", "ns", "tick")
#: seconds per unit (``tick``: 1 / rate)
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: a log sampled this slowly [s] is not a dynamics log: its stamps are in another unit
MAX_PLAUSIBLE_STEP = 1.0
#: the unit checks need this many stamps (a shorter log is refused later as too short anyway)
MIN_STAMPS = 20
#: Accepted rates [Hz]: logs without a time column and tick rates (1 sample per 1000 s .. 10 MHz).
MIN_RATE, MAX_RATE = 1e-3, 1e7


def check_rate(rate, src: str, what: str = "rate") -> float:
    if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)) \
            or not MIN_RATE <= rate <= MAX_RATE:
        raise DataError(f"{what} must be a number of Hz in [{MIN_RATE:g}, {MAX_RATE:g}], got {rate!r}", src)
    return float(rate)


def check_time_unit(time_unit: str | None, rate, src: str) -> None:
    """DataError for a unit not in :data:`TIME_UNITS`, or ``tick`` without a tick rate."""
    if time_unit is None:
        return
    if time_unit not in TIME_UNITS:
        raise DataError(f"{setting('time_unit')} must be one of {list(TIME_UNITS)}, got {time_unit!r}", src)
    if time_unit == "tick":
        if rate is None:
            raise DataError(f"{setting('time_unit', 'tick')} needs the tick rate: {setting('rate', placeholder='HZ')}, "
                            "e.g. 1000 for a 1 kHz controller", src)
        check_rate(rate, src, f"the tick rate ({setting('rate')})")


def _flag_hint(guess: str) -> str:
    if guess == "tick":
        return f"{setting('time_unit', 'tick')} {setting('rate', placeholder='HZ')} with the controller's tick rate"
    return setting("time_unit", guess)


def _guess_unit(t: np.ndarray, column: str, src: str) -> str:
    """The unit of stamps given without one (module docstring); UnitsError when they are not seconds."""
    finite = t[np.isfinite(t)]
    if finite.size < 2:
        return "s"
    if is_tick_name(column):
        raise UnitsError(f"time column '{column}' counts controller ticks (by its name); give their rate: "
                         f"{_flag_hint('tick')}", src)
    start = float(np.abs(finite[0]))
    for unit, low in (("ns", 1e17), ("us", 1e14), ("ms", 1e11)):
        if start >= low:
            return unit
    if finite.size < MIN_STAMPS:
        return "s"
    steps = np.diff(finite)
    step = float(np.median(steps))
    whole = bool(np.all(finite == np.round(finite)) and np.all(steps >= 1))  # a counter: ticks, or integer ms
    if step > MAX_PLAUSIBLE_STEP or whole:
        guess = next((u for u in ("ms", "us", "ns") if step * TIME_SCALE[u] <= MAX_PLAUSIBLE_STEP), "ns")
        looks = f"{guess} (then {1 / (step * TIME_SCALE[guess]):.4g} Hz)"
        if whole:
            raise UnitsError(
                f"time column '{column}' counts in whole steps (median {step:g}, {finite[0]:g}..{finite[-1]:g}): read "
                f"as seconds, a {1 / step:.3g} Hz log, too slow for dynamics; the stamps look like {looks} or controller "
                f"ticks. For {guess} set {_flag_hint(guess)}; for ticks set {_flag_hint('tick')}", src)
        raise UnitsError(
            f"time column '{column}' steps by {step:.6g} (median): a {1 / step:.3g} Hz log, too slow for dynamics; "
            f"the stamps look like {looks}. Store seconds, or set {_flag_hint(guess)}", src)
    return "s"


def to_seconds(t: np.ndarray, time_unit: str | None, rate, column: str, src: str) -> tuple[np.ndarray, str]:
    """``t`` in seconds and the note for ``Trajectory.units['t']``; ``column`` names the time
    column in errors. ``rate`` is the tick rate when ``time_unit == 'tick'``."""
    if time_unit is None:
        unit = _guess_unit(t, column, src)
        if unit == "s":
            return t, "s"
        return t * TIME_SCALE[unit], f"s (converted from {unit}: epoch stamps of that magnitude)"
    if time_unit == "tick":
        hz = check_rate(rate, src, f"the tick rate ({setting('rate')})")
        return t / hz, f"s (converted from ticks at {hz:g} Hz)"
    return t * TIME_SCALE[time_unit], "s" if time_unit == "s" else f"s (converted from {time_unit})"

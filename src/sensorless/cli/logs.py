"""How a command's logs are cut: ``--trim`` (a window for every log, FILE=WINDOW for one,
:class:`sensorless.data.LogTrims`; what a run records about each log: :mod:`sensorless.run.logs`);
the line reporting how two runs of one trajectory were paired."""

from __future__ import annotations

import typer


__all__ = ["log_trims", "print_pairing", "trim_option"]


def trim_option():
    return typer.Option(None, help="time window START:END in seconds after the first sample (negative: before the last); "
                                   "open ends ':49.6', '1.9:'; 'abs:T0:T1' uses the log's own stamps; FILE=START:END "
                                   "for one log (its path or file name; repeatable, wins over a window for all); cut "
                                   "before the time axis is checked")


def log_trims(trim, *paths) -> "LogTrims":
    """The ``--trim`` values parsed (:class:`~sensorless.data.LogTrims`), every FILE= name checked
    against the command's logs ``paths`` (lists of paths)."""
    from ..data.trims import LogTrims

    trims = LogTrims.parse(trim)
    trims.check([p for group in paths for p in (group if isinstance(group, (list, tuple)) else [group])])
    return trims


def print_pairing(pairing: dict) -> None:
    """The console line of a paired run (:class:`sensorless.data.Pairing` ``to_dict()``): the lag and how."""
    from .console import console

    lag = pairing.get("lag_s")
    if lag is None:
        line = f"{pairing['log']}: paired with {pairing['reference']} row by row ({pairing['samples']} samples)"
    else:
        how = "by time" if pairing["align"] == "time" else "row by row (one time grid)"
        ahead = "behind" if lag <= 0 else "ahead of"
        line = (f"{pairing['log']}: lag {lag:+.3f} s ({abs(lag):.3f} s {ahead} {pairing['reference']}, "
                f"r = {pairing['correlation']:.3f}, overlap {pairing['overlap_s']:.2f} s); paired {how}, "
                f"{pairing['samples']} samples")
    console.print(line, highlight=False, soft_wrap=True)

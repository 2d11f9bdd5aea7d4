"""How a command's logs are cut and what a run records about each: ``--trim`` (a window for
every log, FILE=WINDOW for one, :class:`sensorless.data.LogTrims`), ``--skip-bad-rows`` and the
per-log settings (windows, corrupt rows dropped) saved with the results; the line reporting how two
runs of one trajectory were paired."""

from __future__ import annotations

import typer


__all__ = ["log_settings", "log_trims", "preprocessing_settings", "print_pairing", "trim_option"]


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


def preprocessing_settings(logs, *, columns, gains, rate, trim, resample, lowpass, savgol_window, velocity,
                           decimate, max_gap, rest="auto", time_unit=None, base_velocity="auto", pose_max_gap=None,
                           wrench_frames=None, paths=(), log_paths=None) -> dict:
    """settings.preprocessing for result.json: the options (gains resolved per joint name,
    column map parsed, gain suffix moved to ``gains``, ``--angle-unit``), the trim windows and dropped
    corrupt rows of each log (:func:`log_settings`)."""
    from ..data.gains import split_gain_modifiers
    from ..data.limits import current_options
    from ..data.prepare import parse_columns

    cols = parse_columns(columns) if isinstance(columns, str) else columns
    cols, _, _ = split_gain_modifiers(cols, "--columns")
    resolved = next((t.provenance["gains"] for t in logs if "gains" in t.provenance), None)
    return {"columns": cols, "gains": resolved, "rate": rate, "resample": resample, "lowpass": lowpass,
            "savgol_window": savgol_window, "velocity": velocity, "max_gap": max_gap,
            "decimate": decimate, "rest": rest, "time_unit": time_unit,
            "base_velocity": base_velocity, "pose_max_gap": pose_max_gap, "wrench_frames": wrench_frames,
            "angle_unit": current_options().get("angle_unit") or "rad",
            **log_settings(trim, paths, logs, log_paths)}


def log_settings(trim, paths, logs, log_paths=None) -> dict:
    """Per-log settings of a run on the logs at ``paths``: ``trim`` (the window for every log),
    ``trims`` ({log: its window}), ``skip_bad_rows`` and ``rows_dropped`` ({log: the corrupt rows
    dropped}, :mod:`sensorless.data.bad_rows`) of the trajectories ``logs`` read from ``log_paths``
    (default ``paths``)."""
    from ..data.limits import current_options
    from ..data.trims import LogTrims

    paths = [str(p) for p in paths]
    read = paths if log_paths is None else [str(p) for p in log_paths]
    return {**LogTrims.parse(trim).settings(paths), "skip_bad_rows": bool(current_options().get("skip_bad_rows")),
            "rows_dropped": {p: t.provenance["rows_dropped"] for p, t in zip(read, logs)
                             if "rows_dropped" in t.provenance}}


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

"""The logs of a run: read, validated and preprocessed (:func:`~sensorless.data.prepare.load_log` each,
with its trim window), and what a run records about them (``settings.preprocessing``: the options,
each log's window and the corrupt rows dropped)."""

from __future__ import annotations

from ..errors import SensorlessError, setting

__all__ = ["load_logs", "load_training", "first_training_log", "imu_frame_logs", "preprocessing_settings",
           "log_settings"]


def load_logs(paths, robot, columns, rate, lowpass, savgol_window, decimate, *, trim=None, progress=None, **options):
    """Read, validate and preprocess the logs ``paths`` (:func:`load_log` each); ``trim``: the trim
    values or their :class:`~sensorless.data.LogTrims` (each log gets its window); ``progress(1)`` after
    each file."""
    from ..data.prepare import load_log
    from ..data.trims import LogTrims

    trims = LogTrims.parse(trim)
    logs = []
    for p in paths:
        logs.append(load_log(p, robot, columns, rate, lowpass, savgol_window, decimate, trim=trims.window_for(p),
                             **options))
        if progress is not None:
            progress(1)
    return logs


def load_training(data, r, prep: dict, skip_bad: bool, progress=None):
    """Every training log in memory: (logs, paths used, [(path, error)] skipped); with ``skip_bad`` a file
    that fails is left out and reported. ``progress(1)`` after each file."""
    if not skip_bad:
        return load_logs(data, r, **prep, progress=progress), data, []
    from ..data.limits import read_options
    from ..data.prepare import load_log

    train, used, skipped = [], [], []
    with read_options(skip_bad=True):  # corrupt bag/MCAP chunks: the rest of the file is read, with a warning
        for p in data:
            try:
                train.append(load_log(p, r, **prep))
                used.append(p)
            except SensorlessError as exc:
                skipped.append((str(p), str(exc) if str(p) in str(exc) else f"{p}: {exc}"))
            if progress is not None:
                progress(1)
    if not train:
        raise SensorlessError(f"every {setting('logs.data')} file was skipped: " + "; ".join(e for _, e in skipped))
    return train, used, skipped


def first_training_log(data, r, prep: dict, skip_bad: bool = False) -> list:
    """The first training log (friction law, contact rows, torque plot), if this machine has it; a file
    here that fails raises its error, as the workers would (one line, as a single-process run), unless
    ``skip_bad`` (then it is left to the workers to skip)."""
    import os

    from ..data.prepare import load_log

    if not os.path.isfile(str(data[0])):
        return []
    try:
        return [load_log(data[0], r, **prep)]
    except SensorlessError:
        if skip_bad:
            return []
        raise


def imu_frame_logs(logs, robot, frame: str, savgol_window):
    """Recompute base_a with the accelerometer in model frame ``frame`` (needs 'imu_acc')."""
    from ..data.prepare import with_imu_frame

    return [with_imu_frame(t, robot, frame, savgol_window) for t in logs]


def preprocessing_settings(logs, *, columns, gains, rate, trim, resample, lowpass, savgol_window, velocity,
                           decimate, max_gap, rest="auto", time_unit=None, base_velocity="auto", pose_max_gap=None,
                           wrench_frames=None, paths=(), log_paths=None) -> dict:
    """settings.preprocessing for result.json: the options (gains resolved per joint name,
    column map parsed, gain suffix moved to ``gains``, the angle unit), the trim windows and dropped
    corrupt rows of each log (:func:`log_settings`)."""
    from ..data.gains import split_gain_modifiers
    from ..data.limits import current_options
    from ..data.prepare import parse_columns

    cols = parse_columns(columns) if isinstance(columns, str) else columns
    cols, _, _ = split_gain_modifiers(cols, setting("logs.columns"))
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

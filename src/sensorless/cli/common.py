"""Shared CLI pieces: the typer apps, error guard, atomic output directories, progress bars."""

from __future__ import annotations

import contextlib
import functools
import math
import os
import shutil
import tempfile
import warnings
from pathlib import Path
from typing import Iterator, List, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from ..errors import OptionError, SensorlessError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Dynamic models for robots without torque or force sensors.")
bench_app = typer.Typer(no_args_is_help=True, help="Speed and scale benchmarks (JSON output).")
experiment_app = typer.Typer(no_args_is_help=True, help="Reproductions of the papers' studies (JSON + figures).")
app.add_typer(bench_app, name="benchmark")
app.add_typer(experiment_app, name="experiment")
console = Console(stderr=False)
err_console = Console(stderr=True)


def one_line(text: object, limit: int = 2000) -> str:
    """``text`` with every run of whitespace (newlines included) collapsed to one space."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def _print_line(label: str, style: str, message: str) -> None:
    # Text, not markup: messages may hold "[...]" (C++ diagnostics, lists) that rich would eat
    err_console.print(Text.assemble((label, style), " ", message), highlight=False, soft_wrap=True)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    name = getattr(category, "__name__", "Warning")
    prefix = "" if name in ("UserWarning", "IdentifiabilityWarning", "DataWarning") else f"{name}: "
    _print_line("warning:", "yellow", prefix + one_line(message))


def guarded(fn):
    """Turn SensorlessError (and any unexpected error) into one line + non-zero exit; print
    every warning (ours, numpy's, torch's) on one line too."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = _show_warning
            try:
                return fn(*args, **kwargs)
            except typer.Exit:
                raise
            except SensorlessError as exc:
                _print_line("error:", "bold red", one_line(exc))
                raise typer.Exit(2) from None
            except Exception as exc:  # noqa: BLE001 - last line of defence for the user
                if os.environ.get("SENSORLESS_DEBUG"):
                    raise
                _print_line("internal error:", "bold red",
                            f"{type(exc).__name__}: {one_line(exc, 500)} (set SENSORLESS_DEBUG=1 for a traceback)")
                raise typer.Exit(3) from None

    return wrapper


@contextlib.contextmanager
def atomic_outdir(out: Path, force: bool) -> Iterator[Path]:
    """Write into a temporary sibling directory; move it to ``out`` only on success."""
    out = Path(out)
    if out.exists() and not force:
        raise SensorlessError(f"{out}: output directory exists; pass --force to replace it")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    os.replace(tmp, out)


def progress_bar() -> Progress:
    return Progress(
        TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=err_console, transient=True,
    )


def parse_columns(spec: Optional[str]) -> Optional[dict]:
    """'q=0:7;v=vel_{joint};tau=a|b|c' -> {'q': '0:7', 'v': 'vel_{joint}', 'tau': ['a','b','c']}."""
    if not spec:
        return None
    out: dict = {}
    for part in spec.split(";"):
        if not part.strip():
            continue
        if "=" not in part:
            raise SensorlessError(f"--columns: '{part}' is not FIELD=SPEC (e.g. 'q=0:7;tau=14:21')")
        key, val = (s.strip() for s in part.split("=", 1))
        out[key] = val.split("|") if "|" in val else val
    return out


def load_robot_arg(robot: str, lock: Optional[List[str]], floating: Optional[bool]):
    from ..robot import load_robot

    return load_robot(robot, lock_joints=lock or (), floating_base=floating)


def check_preprocessing(rate, lowpass, savgol_window, decimate) -> None:
    """OptionError for preprocessing options no log can use (zero, negative, NaN, absurd)."""
    from ..data.readers import MAX_RATE, MIN_RATE

    if rate is not None and not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
        raise OptionError(f"--rate must be a sample rate in [{MIN_RATE:g}, {MAX_RATE:g}] Hz, got {rate!r}")
    if lowpass is not None and not (math.isfinite(lowpass) and lowpass > 0):
        raise OptionError(f"--lowpass must be a cut-off frequency > 0 Hz, got {lowpass!r}")
    if savgol_window is not None and (savgol_window < 5 or savgol_window % 2 == 0):
        raise OptionError(f"--savgol-window must be an odd number of samples >= 5, got {savgol_window!r}")
    if decimate is not None and decimate < 1:
        raise OptionError(f"--decimate must be an integer >= 1, got {decimate!r}")


def load_logs(paths, robot, columns, rate, lowpass, savgol_window, decimate, outliers: str = "error"):
    """Read, validate and preprocess logs given on the command line.

    ``outliers`` ("error" | "drop" | "keep") is applied to the raw log; after dropping samples
    a log that needs filtering is resampled onto its uniform grid first (linear interpolation
    over the gaps).
    """
    from ..data import decimate as _decimate
    from ..data import lowpass as _lowpass
    from ..data import base_acceleration, read_trajectory, resample_uniform, savgol_derivatives
    from ..data.outliers import OUTLIER_MODES

    check_preprocessing(rate, lowpass, savgol_window, decimate)
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"--outliers must be one of {', '.join(OUTLIER_MODES)}, got {outliers!r}")
    logs = []
    for p in paths:
        traj = read_trajectory(p, columns=parse_columns(columns), rate=rate, robot=robot, outliers=outliers)
        filtering = lowpass or traj.v is None or traj.a is None or savgol_window or (decimate and decimate > 1)
        if "outlier" in traj.units.get("processing", "") and filtering:  # samples were dropped
            traj = resample_uniform(traj)
        if lowpass:
            traj = _lowpass(traj, lowpass)
        if traj.v is None or traj.a is None or savgol_window:
            traj = savgol_derivatives(traj, window=savgol_window or 11)
        if traj.base_v is not None and traj.base_q is not None and (traj.base_a is None or savgol_window):
            traj = base_acceleration(traj, window=savgol_window or 11)  # linear part from imu_acc if logged
        if decimate and decimate > 1:
            traj = _decimate(traj, decimate)
        logs.append(traj)
    return logs


ROBOT_HELP = "URDF path, MJCF path, or example-robot-data name (e.g. panda, ur5, solo12)"

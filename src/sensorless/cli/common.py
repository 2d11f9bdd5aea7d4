"""Shared CLI pieces: the typer apps, error guard, atomic output directories, progress bars."""

from __future__ import annotations

import contextlib
import functools
import os
from pathlib import Path
from typing import Iterable, Iterator, List, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from ..errors import SensorlessError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Dynamic models for robots without torque or force sensors.")
bench_app = typer.Typer(no_args_is_help=True, help="Speed and scale benchmarks (JSON output).")
experiment_app = typer.Typer(no_args_is_help=True, help="Reproductions of the papers' studies (JSON + figures).")
app.add_typer(bench_app, name="benchmark")
app.add_typer(experiment_app, name="experiment")
console = Console(stderr=False)
err_console = Console(stderr=True)


def guarded(fn):
    """Turn SensorlessError (and any unexpected error) into one line + non-zero exit."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except typer.Exit:
            raise
        except SensorlessError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except Exception as exc:  # noqa: BLE001 - last line of defence for the user
            if os.environ.get("SENSORLESS_DEBUG"):
                raise
            err_console.print(
                f"[bold red]internal error:[/] {type(exc).__name__}: {exc} (set SENSORLESS_DEBUG=1 for a traceback)",
                highlight=False, soft_wrap=True,
            )
            raise typer.Exit(3) from None

    return wrapper


@contextlib.contextmanager
def atomic_outdir(out: Path, force: bool, inputs: Iterable = ()) -> Iterator[Path]:
    """:func:`sensorless.io.atomic_output_dir` for a command: the manifest records the command
    and its options; ``inputs`` (files or folders the command reads) are never replaced."""
    from ..io import atomic_output_dir

    command = None
    ctx = _current_context()
    if ctx is not None:
        command = {"name": " ".join(["sensorless", *ctx.command_path.split()[1:]]), "options": {
            k: v if isinstance(v, (str, int, float, bool, list, tuple, Path)) or v is None else str(v)
            for k, v in ctx.params.items()}}
    with atomic_output_dir(out, force, inputs=inputs, command=command) as tmp:
        yield tmp


def _current_context():
    """The running command's click context (typer ≥ 0.2x vendors click as ``typer._click``)."""
    try:
        from typer.main import get_current_context
    except ImportError:  # pragma: no cover - older typer on plain click
        from click import get_current_context
    return get_current_context(silent=True)


def output_file(out: Path, inputs: Iterable = ()) -> Path:
    """Check a single-file ``--out`` (not a directory, not an input)."""
    from ..io import check_output_file

    return check_output_file(out, inputs)


def path_inputs(*values) -> list:
    """The command-line values that are existing paths (logs, URDFs, data folders): never replaced."""
    out = []
    for v in values:
        for x in (v if isinstance(v, (list, tuple)) else [v]):
            if x is not None and str(x) and os.path.exists(str(x)):
                out.append(Path(str(x)))
    return out


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


def load_logs(paths, robot, columns, rate, lowpass, savgol_window, decimate):
    """Read, validate and preprocess logs given on the command line."""
    from ..data import decimate as _decimate
    from ..data import lowpass as _lowpass
    from ..data import base_acceleration, read_trajectory, savgol_derivatives

    logs = []
    for p in paths:
        traj = read_trajectory(p, columns=parse_columns(columns), rate=rate, robot=robot)
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

"""Shared CLI pieces: the typer apps, error guard, atomic output directories, progress bars."""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator, List, Optional

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
    """A URDF/MJCF/example-robot-data robot, or a model shipped in code ('dvrk_psm': the PSM in
    motor coordinates, a transmission's coordinate robot)."""
    from ..robot import load_robot
    from ..robots.dvrk_psm import PSM_NAMES, psm_robot

    if str(robot).lower() in PSM_NAMES:
        if lock or floating:
            raise SensorlessError(f"--robot {robot}: --lock and --floating-base do not apply to the PSM model")
        return psm_robot()
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


ROBOT_HELP = "URDF path, MJCF path, example-robot-data name (e.g. panda, ur5, solo12), or dvrk_psm (coupled PSM model, motor coordinates)"

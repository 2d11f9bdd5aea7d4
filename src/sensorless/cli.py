"""Command-line interface (typer). Every SensorlessError becomes one red line and exit code 2."""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator, List, Optional

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from .errors import ExcitationError, SensorlessError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Dynamic models for robots without torque or force sensors.")
bench_app = typer.Typer(no_args_is_help=True, help="Speed and scale benchmarks (JSON output).")
app.add_typer(bench_app, name="benchmark")
console = Console(stderr=False)
err_console = Console(stderr=True)


def _guarded(fn):
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
    from .robot import load_robot

    return load_robot(robot, lock_joints=lock or (), floating_base=floating)


def load_logs(paths, robot, columns, rate, lowpass, savgol_window, decimate):
    """Read, validate and preprocess logs given on the command line."""
    from .data import decimate as _decimate
    from .data import lowpass as _lowpass
    from .data import read_trajectory, savgol_derivatives

    logs = []
    for p in paths:
        traj = read_trajectory(p, columns=parse_columns(columns), rate=rate, robot=robot)
        if lowpass:
            traj = _lowpass(traj, lowpass)
        if traj.v is None or traj.a is None or savgol_window:
            traj = savgol_derivatives(traj, window=savgol_window or 11)
        if decimate and decimate > 1:
            traj = _decimate(traj, decimate)
        logs.append(traj)
    return logs


ROBOT_HELP = "URDF path, MJCF path, or example-robot-data name (e.g. panda, ur5, solo12)"


@app.command()
@_guarded
def identify(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    data: List[Path] = typer.Option(..., help="training log(s): .csv .npz .parquet .h5"),
    validate: List[Path] = typer.Option([], help="held-out log(s) to report metrics on"),
    method: str = typer.Option("ols", help="ols | wls"),
    out: Path = typer.Option(..., help="output directory (written atomically)"),
    joint_terms: str = typer.Option("fv,fc,offset,armature", help="per-joint terms, comma separated"),
    columns: Optional[str] = typer.Option(None, help="column map, e.g. 'q=0:7;v=7:14;tau=14:21' or 'q=pos_{joint}'"),
    rate: Optional[float] = typer.Option(None, help="sample rate [Hz] for logs without a time column"),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off [Hz] before identification"),
    savgol_window: Optional[int] = typer.Option(None, help="recompute v, a from q with this Savitzky-Golay window"),
    decimate: int = typer.Option(1, help="keep every n-th sample (after anti-alias filtering)"),
    lock: Optional[List[str]] = typer.Option(None, help="joints to lock (e.g. gripper fingers)"),
    floating_base: Optional[bool] = typer.Option(None, "--floating-base/--fixed-base"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """Identify a dynamic model from logs; write result.json, model.urdf, joint_terms.json, torques.png."""
    from .estimators import CADModel
    from .identification import identify as _identify
    from .regressor import ModelStructure
    from .report import metrics_table, plot_torques

    r = load_robot_arg(robot, lock, floating_base)
    with atomic_outdir(out, force) as tmp:
        train = load_logs(data, r, columns, rate, lowpass, savgol_window, decimate)
        val = load_logs(validate, r, columns, rate, lowpass, savgol_window, decimate)
        structure = ModelStructure(r, joint_terms=tuple(t for t in joint_terms.split(",") if t))
        total = sum(len(t) for t in train)
        with progress_bar() as bar:
            task = bar.add_task("regressor", total=total)
            try:
                result = _identify(structure, train, method=method, progress=lambda n: bar.advance(task, n))
            except ExcitationError as exc:
                raise ExcitationError(f"{', '.join(map(str, data))}: {exc}") from None
        result.settings.update({"data": [str(p) for p in data], "validate": [str(p) for p in validate],
                                "lowpass_hz": lowpass, "savgol_window": savgol_window, "decimate": decimate,
                                "columns": columns, "rate": rate})
        doc = result.to_dict()
        cad = CADModel(r)
        doc["validation"] = {}
        for p, traj in zip(validate, val):
            m_id, m_cad = result.evaluate(traj), cad.score(traj)
            doc["validation"][str(p)] = {method: m_id.to_dict(), "cad": m_cad.to_dict()}
            console.print(metrics_table(f"held-out {Path(p).name}", {"CAD": m_cad, method.upper(): m_id}))
        shown = val[0] if val else train[0]
        plot_torques(shown.t, structure.target(shown), {method.upper(): result.predict(shown), "CAD": cad.predict(shown)},
                     structure.row_names, tmp / "torques.png", title=f"{r.name}: {'held-out' if val else 'training'} torques")
        _export(result, tmp, doc)
        from .identification.result import write_json_atomic

        write_json_atomic(doc, tmp / "result.json")
    console.print(f"rank {result.base.rank}, condition number {result.diagnostics['condition_number']:.1f}; wrote {out}/")


def _export(result, tmp: Path, doc: dict) -> None:
    """URDF + joint terms; a model that is not a physical body is reported, not exported."""
    from .errors import SensorlessError as _E
    from .export import write_joint_terms, write_urdf
    from .parameters import JointTerms, check_physical_consistency

    reports = check_physical_consistency(result.inertial_parameters, list(result.robot.body_names))
    bad = [rep.name for rep in reports if not rep.consistent]
    doc["physical_consistency"] = {"inconsistent_bodies": bad, "n_bodies": len(reports)}
    terms = JointTerms.from_dict(result.joint_terms())
    write_joint_terms(terms, tmp / "joint_terms.json")
    try:
        write_urdf(result.robot, result.inertial_parameters, tmp / "model.urdf", joint_terms=terms)
        doc["urdf"] = "model.urdf"
    except _E as exc:
        doc["urdf"] = None
        doc["urdf_error"] = str(exc)
        err_console.print(f"[yellow]warning:[/] no URDF written: {exc}")


@app.command()
@_guarded
def predict(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    model: Path = typer.Option(..., help="result.json (or its directory) from `sensorless identify`"),
    data: Path = typer.Option(..., help="log to predict"),
    out: Path = typer.Option(..., help="output .npz with t, tau_pred (and tau_measured, metrics if available)"),
    columns: Optional[str] = typer.Option(None),
    rate: Optional[float] = typer.Option(None),
    savgol_window: Optional[int] = typer.Option(None),
    lock: Optional[List[str]] = typer.Option(None),
    floating_base: Optional[bool] = typer.Option(None, "--floating-base/--fixed-base"),
) -> None:
    """Predict joint torques of a log with an identified model."""
    from .estimators import load_parameters
    from .identification.metrics import torque_metrics
    from .report import metrics_table

    r = load_robot_arg(robot, lock, floating_base)
    path = model / "result.json" if model.is_dir() else model
    structure, params = load_parameters(path, r)
    (traj,) = load_logs([data], r, columns, rate, None, savgol_window, 1)
    pred = structure.torques(params, traj)
    arrays = {"t": traj.t, "tau_pred": pred, "joints": np.array(structure.row_names)}
    if traj.tau is not None:
        meas = structure.target(traj)
        arrays["tau_measured"] = meas
        console.print(metrics_table(Path(data).name, {"model": torque_metrics(meas, pred, structure.row_names)}))
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".npz")
    os.close(fd)
    np.savez(tmp, **arrays)
    os.replace(tmp, out)
    console.print(f"wrote {out}")


@app.command()
@_guarded
def demo(
    out: Path = typer.Option(Path("demo_output"), help="output directory"),
    seed: int = typer.Option(0, help="random seed"),
) -> None:
    """End-to-end example on a simulated Panda: excite, identify, validate, export."""
    from .demo import run_demo

    with atomic_outdir(out, force=True) as tmp:
        run_demo(tmp, seed=seed, console=console)
    console.print(f"wrote {out}/")


@bench_app.command("identify")
@_guarded
def bench_identify(
    robot: str = typer.Option("panda", help=ROBOT_HELP),
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts"),
    out: Path = typer.Option(Path("benchmarks/results/identify.json")),
) -> None:
    """Identification wall time, peak memory and per-sample cost vs a bare regressor call."""
    from .bench import bench_identify as run

    res = run(robot, [int(float(s)) for s in samples.split(",")], console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    from .identification.result import write_json_atomic

    write_json_atomic(res, out)
    console.print(f"wrote {out}")


def main() -> None:  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    main()

"""`sensorless excite` (optimised Fourier excitation) and `sensorless experiment psm-identify`
(the dVRK PSM held-out identification)."""

from __future__ import annotations

import math

from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from ..errors import ExcitationError, OptionError
from .common import (
    ROBOT_HELP,
    app,
    atomic_outdir,
    console,
    err_console,
    experiment_app,
    guarded,
    load_robot_arg,
    path_inputs,
)

from ..robots.dvrk_psm import PSM_NAMES  # noqa: E402  (re-exported: names `--robot` accepts for the PSM)


def _parse_box(spec: str):
    """'FRAME:xmin,ymin,zmin:xmax,ymax,zmax' with '-' for an open side."""
    from ..excitation_design import CartesianBox

    parts = spec.split(":")
    if len(parts) != 3:
        raise ExcitationError(f"--box '{spec}': expected FRAME:xmin,ymin,zmin:xmax,ymax,zmax ('-' for open sides)")

    def vec(txt: str, fill: float) -> tuple[float, float, float]:
        vals = [v.strip() for v in txt.split(",")]
        if len(vals) != 3:
            raise ExcitationError(f"--box '{spec}': each bound needs 3 comma-separated values")
        try:
            return tuple(fill if v in ("-", "") else float(v) for v in vals)  # type: ignore[return-value]
        except ValueError:
            raise ExcitationError(f"--box '{spec}': bounds must be numbers or '-'") from None

    return CartesianBox(parts[0], vec(parts[1], -np.inf), vec(parts[2], np.inf))


def _check_options(**opts) -> None:
    """Numeric options of `excite`: whole numbers in range, finite positive reals."""
    whole = {"harmonics": (1, 100), "n_samples": (4, 100_000), "maxiter": (1, 100_000), "seed": (0, 2**63 - 1)}
    for name, (lo, hi) in whole.items():
        if not lo <= opts[name] <= hi:
            raise ExcitationError(f"--{name.replace('_', '-')} must be a whole number in [{lo}, {hi}], got {opts[name]}")
    if not (np.isfinite(opts["base_freq"]) and 0 < opts["base_freq"] <= 1e3):
        raise ExcitationError(f"--base-freq must be a finite frequency in (0, 1000] Hz, got {opts['base_freq']}")
    f = opts["position_fraction"]
    if not (np.isfinite(f) and 0 < f <= 1):
        raise ExcitationError(f"--position-fraction must be in (0, 1] (a fraction of each joint's range), got {f}")
    for name in ("max_velocity", "max_acceleration"):
        if not (np.isfinite(opts[name]) and opts[name] > 0):
            raise ExcitationError(f"--{name.replace('_', '-')} must be finite and > 0, got {opts[name]}")


@app.command()
@guarded
def excite(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    out: Path = typer.Option(..., help="output directory (written atomically): excitation.json, trajectory.npz"),
    harmonics: int = typer.Option(5, help="Fourier harmonics per joint"),
    base_freq: float = typer.Option(0.1, help="base frequency f0 [Hz] (period 1/f0)"),
    criterion: str = typer.Option("cond", help="cond (condition number of the column-equilibrated base regressor) | dopt (−log det)"),
    rate: float = typer.Option(200.0, help="sample rate [Hz] of the exported trajectory"),
    periods: int = typer.Option(1, help="whole periods in the exported trajectory (≥ 1)"),
    seed: int = typer.Option(0, help="seed of the random start (and of the random baseline)"),
    n_samples: int = typer.Option(200, help="samples per period in the objective"),
    maxiter: int = typer.Option(100, help="SLSQP iterations"),
    joint_terms: str = typer.Option("fv,fc,offset,armature", help="per-joint terms of the identified model (URDF robots)"),
    position_fraction: float = typer.Option(0.8, help="fraction of each joint range used, about mid-range (URDF robots)"),
    max_velocity: float = typer.Option(2.0, help="velocity limit [rad/s] (capped by the model's; URDF robots)"),
    max_acceleration: float = typer.Option(10.0, help="acceleration limit [rad/s²] (URDF robots)"),
    start_at_rest: bool = typer.Option(False, "--start-at-rest/--free-start", help="zero velocity and acceleration at t = 0 (costs some conditioning)"),
    box: List[str] = typer.Option([], help="Cartesian box for a frame: 'FRAME:xmin,ymin,zmin:xmax,ymax,zmax' ('-' = open)"),
    lock: Optional[List[str]] = typer.Option(None, help="joints to lock (e.g. gripper fingers)"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """Optimise a Fourier excitation (joint limits as hard constraints); export coefficients and samples.

    The samples written are checked against the excitation limits and the robot model's own
    limits; a trajectory that leaves them is refused (exit 2, nothing written)."""
    from ..excitation_design import ExcitationLimits, check_export, design_excitation
    from ..regressor import ModelStructure

    _check_options(harmonics=harmonics, base_freq=base_freq, n_samples=n_samples, maxiter=maxiter, seed=seed,
                   position_fraction=position_fraction, max_velocity=max_velocity, max_acceleration=max_acceleration)
    check_export(rate, periods, harmonics, base_freq)

    if robot.lower() in PSM_NAMES:
        from ..robots.dvrk_psm import PSM_LIMITS, psm_structure

        structure = psm_structure()
        limits = ExcitationLimits(structure.robot.joint_names, PSM_LIMITS["lower"], PSM_LIMITS["upper"],
                                  PSM_LIMITS["velocity"], PSM_LIMITS["acceleration"])
    else:
        r = load_robot_arg(robot, lock, False)
        structure = ModelStructure(r, joint_terms=tuple(t for t in joint_terms.split(",") if t))
        limits = ExcitationLimits.from_robot(r, position_fraction, max_velocity, max_acceleration)
    boxes = [_parse_box(b) for b in box]
    with atomic_outdir(out, force, inputs=path_inputs(robot)) as tmp:
        with err_console.status("optimising excitation …") as status:
            design = design_excitation(
                structure, limits, harmonics=harmonics, base_freq=base_freq, criterion=criterion,
                n_samples=n_samples, cartesian=boxes, start_at_rest=start_at_rest, seed=seed, maxiter=maxiter,
                progress=lambda i, f: status.update(f"optimising excitation … iteration {i}, objective {f:.4g}"),
            )
        design.save(tmp, rate=rate, periods=periods)
    m, b = design.metrics, design.random_metrics
    console.print(
        f"[bold]{structure.robot.name}[/]: base-regressor condition number (column-equilibrated) "
        f"{m['cond']:.4g} optimised vs {b['cond']:.4g} random (seed {seed}; median of {design.settings['n_random']} seeds "
        f"{b['cond_median']:.4g}) → {design.improvement:.1f}× lower; raw {m['cond_raw']:.4g} vs {b['cond_raw']:.4g}; "
        f"{design.settings['iterations']} iterations, {design.settings['seconds']:.1f} s"
    )
    worst = max(design.limit_violation.values())  # save() refused any excess on the written samples
    console.print(f"limits respected on the written samples and a dense grid (largest excess {worst:.3g}); wrote {out}")


@experiment_app.command("psm-identify")
@guarded
def psm_identify(
    out: Path = typer.Option(..., help="output directory (written atomically): result.json (loadable by predict, "
                                       "estimate-force, payload), drive_terms.json, psm_identification.json"),
    data: Optional[Path] = typer.Option(None, help="folder of the WPI dVRK data set (the one holding data/psm/...)"),
    train: Optional[Path] = typer.Option(None, help="training log (header-less CSV: q, q̇, effort × 7, 200 Hz)"),
    test: Optional[Path] = typer.Option(None, help="held-out log, same format"),
    params: Optional[Path] = typer.Option(None, help="optional: the authors' params.json, for comparison"),
    save: str = typer.Option("ols", help="which model result.json holds: ols | wls | lmi"),
    cutoff: float = typer.Option(5.4, help="zero-phase low-pass cut-off [Hz] on q, q̇ and effort"),
    smoothing: str = typer.Option("cv", help="Coulomb smoothing ε [rad/s], or 'cv' (3-fold cross-validation on the "
                                             "training log; slow)"),
    lmi: bool = typer.Option(False, help="also solve the physically consistent (LMI) problem"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """Identify the PSM on --train (or one_results), predict --test (or two_results); compare with
    the published parameters when given. The same as `sensorless identify --robot dvrk_psm --columns
    'q=0:7;v=7:14;tau=14:21' --rate 200 --lowpass 5.4`, plus Coulomb smoothing chosen by cross-validation."""
    from rich.table import Table

    from ..identification.result import write_json_atomic
    from ..robots.dvrk_psm_study import psm_identification_study
    from .core import _export

    if data is None and (train is None or test is None):
        raise OptionError("give --data (the WPI folder) or both --train and --test")
    if smoothing != "cv":
        try:
            smoothing = float(smoothing)
            if not (math.isfinite(smoothing) and smoothing >= 0):
                raise ValueError
        except ValueError:
            raise OptionError(f"--smoothing must be a number or 'cv', got '{smoothing}'") from None
    if save not in ("ols", "wls", "lmi"):
        raise OptionError(f"--save must be ols, wls or lmi, got '{save}'")
    with atomic_outdir(out, force, inputs=path_inputs(data, train, test, params)) as tmp:
        results: dict = {}
        with err_console.status("identifying the PSM (smoothing chosen by cross-validation on the training log) …"):
            report = psm_identification_study(
                data, train=train, test=test, params=params, results=results, cutoff_hz=cutoff, smoothing=smoothing,
                lmi={"ellipsoids": False, "regularization": None, "gamma": 0.0} if (lmi or save == "lmi") else None,
            )
        write_json_atomic(report, tmp / "psm_identification.json")
        result = results[save]
        result.settings.update({
            "data": [report["settings"]["train"]], "validate": [report["settings"]["test"]],
            "preprocessing": {"columns": {"q": "0:7", "v": "7:14", "tau": "14:21"}, "rate": 200.0, "lowpass": cutoff,
                              "velocity": "logged", "savgol_window": None, "resample": None, "gains": None,
                              "max_gap": None},
        })
        doc = result.to_dict()
        doc["validation"] = {report["settings"]["test"]: report["identified"][save]}
        _export(result, tmp, doc)
        write_json_atomic(doc, tmp / "result.json")
    table = Table(title=f"held-out NRMSE (RMSE / range), ε = {report['settings']['coulomb_smoothing']:g}")
    table.add_column("model")
    for c in report["coordinates"]:
        table.add_column(c, justify="right")
    rows = {k.upper(): v for k, v in report["identified"].items()}
    if "published" in report:
        rows["published"] = report["published"]
    for name, entry in rows.items():
        table.add_row(name, *(f"{entry['test_nrmse'][c]:.4g}" for c in report["coordinates"]))
    console.print(table)
    console.print(f"wrote {out}/ (result.json: the {save.upper()} model)")

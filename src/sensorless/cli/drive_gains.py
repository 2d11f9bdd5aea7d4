"""`sensorless drive-gains`: per-joint drive gains τ = K i from an unloaded/loaded pair of logs."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..errors import DataError, OptionError
from .common import (
    log_reading_options,
    robot_source_options,
    MultiValueCommand,
    app,
    guarded,
    load_robot_arg,
    output_file,
    path_inputs,
    resample_option,
    time_unit_option,
    force_option,
    lock_option,
    robot_option,
)
from ..run.logs import load_logs, log_settings
from .console import console, err_console, safe
from .logs import log_trims, print_pairing, trim_option
from .options import ALIGN_HELP, RATE_HELP, Align, TimeUnit
from .progress import progress_bars

__all__ = ["drive_gains"]


@app.command("drive-gains", cls=MultiValueCommand)
@guarded
@robot_source_options
@log_reading_options()
def drive_gains(
    robot: str = robot_option(),
    unloaded: Path = typer.Option(..., help="log of a trajectory run without the payload (motor currents)"),
    loaded: Path = typer.Option(..., help="the same trajectory run with the known payload"),
    payload_mass: float = typer.Option(..., help="known payload mass [kg]"),
    frame: str = typer.Option(..., help="link or frame carrying the payload, e.g. tool0"),
    com: Optional[str] = typer.Option(None, help="payload CoM 'x,y,z' [m] in the frame (default its origin); off the "
                                                 "last joint's axis, or that joint's gain cannot be seen"),
    out: Path = typer.Option(..., help="output JSON: {'gains': {joint: K}, intervals, ...}, readable by --gains"),
    nominal_gains: Optional[str] = typer.Option(None, help="gains written for joints the pair does not identify "
                                                           "(same forms as --gains)"),
    columns: Optional[str] = typer.Option(None, help="column map; the currents on 'tau' or 'current', e.g. "
                                                     "'q=pos_{joint};v=vel_{joint};tau=i_{joint}'"),
    rate: Optional[float] = typer.Option(None, help=RATE_HELP),
    time_unit: Optional[TimeUnit] = time_unit_option(),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off [Hz]"),
    savgol_window: Optional[int] = typer.Option(None, help="Savitzky-Golay window for v̇ (from the logged v)"),
    trim: Optional[List[str]] = trim_option(),
    resample: str = resample_option(),
    offset: bool = typer.Option(True, help="fit a current offset per joint (drift between the two runs)"),
    align: Align = typer.Option(Align.auto, help=ALIGN_HELP),
    block_seconds: Optional[float] = typer.Option(None, help="block length [s] of the bootstrap / HAC (default: from "
                                                             "the residual autocorrelation, >= 1 s)"),
    n_boot: int = typer.Option(1000, help="moving-block bootstrap resamples"),
    seed: int = typer.Option(0, help="bootstrap seed"),
    lock: Optional[List[str]] = lock_option("joints to lock"),
    accept_misfit: bool = typer.Option(False, help="write the gains even where the payload's torque does not "
                                                   "explain the current difference (residual > 3× the noise)"),
    force: bool = force_option(),
) -> None:
    """Identify per-joint drive gains K (τ = K·i) from two runs of one trajectory, without and
    with a known payload: K_j (i_loaded − i_unloaded)_j = τ_payload,j, least squares on
    the currents, 95 % intervals from a moving-block bootstrap and HAC (correlated noise).
    The output JSON is a gains file for --gains of identify, predict, payload, monitor."""
    import numpy as np

    from ..data.gains import resolve_gains
    from ..data.limits import current_options
    from ..identification.drive_gains import identify_drive_gains
    from ..io import write_json_atomic
    from .payload import parse_vector

    if not (np.isfinite(payload_mass) and payload_mass > 0):
        raise OptionError(f"--payload-mass must be a positive number of kg, got {payload_mass}")
    if n_boot < 10:
        raise OptionError(f"--n-boot must be at least 10, got {n_boot}")
    if block_seconds is not None and not (np.isfinite(block_seconds) and block_seconds > 0):
        raise OptionError(f"--block-seconds must be > 0, got {block_seconds}")
    output_file(out, path_inputs(robot, unloaded, loaded), force)
    r = load_robot_arg(robot, lock, False)
    c = parse_vector(com, "--com")
    trims = log_trims(trim, [unloaded, loaded])
    u, lo = load_logs([unloaded, loaded], r, columns, rate, lowpass, savgol_window, 1, trim=trims, resample=resample,
                      time_unit=time_unit)
    with progress_bars() as bars:
        res = identify_drive_gains(r, u, lo, payload_mass=payload_mass, payload_frame=frame, payload_com=c,
                                   offset=offset, align=align, block_seconds=block_seconds, n_boot=n_boot, seed=seed,
                                   progress=bars.callback("drive-gain block bootstrap (resamples)"))
    print_pairing(res.diagnostics["alignment"])
    _check_misfit(res, loaded, accept_misfit)
    doc = res.to_dict()
    written = dict(doc["gains"])
    nominal = resolve_gains(nominal_gains, r.actuated_joints, "--nominal-gains") if nominal_gains else None
    missing = [j for j, ok in zip(res.joints, res.identified) if not ok]
    for j in missing:
        if nominal is not None:
            written[j] = float(nominal[list(r.actuated_joints).index(j)])
        elif not (np.isfinite(written[j]) and written[j] > 0):
            raise DataError(f"the pair does not identify the gain of '{j}' (no or too little payload torque there, "
                            "or no payload difference between the logs); "
                            "give --nominal-gains for it, or move the payload's CoM (--com) off that joint's axis",
                            str(loaded))
    doc["gains"] = written
    doc["estimated_gains"] = dict(zip(res.joints, map(float, res.gains)))
    doc["from_nominal"] = missing if nominal is not None else []
    doc.update({"robot": r.name, "unloaded": str(unloaded), "loaded": str(loaded)})
    doc["settings"].update({"columns": columns, "resample": resample, "savgol_window": savgol_window,
                            "lowpass": lowpass, "angle_unit": current_options().get("angle_unit") or "rad",
                            **log_settings(trims, [unloaded, loaded], [u, lo])})
    write_json_atomic(doc, out)
    _print(res, missing, nominal is not None)
    console.print(f"wrote {out}")


def _check_misfit(res, loaded: Path, accept: bool) -> None:
    """Refuse gains the payload description does not explain (identification.drive_gains, "Misfit")."""
    from ..identification.drive_gains import MAX_MISFIT

    bad = [j for j, m in zip(res.joints, res.misfit) if m]
    if not bad:
        return
    ratio = res.diagnostics["residual_over_noise"]
    text = (f"the payload's torque does not explain the loaded − unloaded current difference on "
            f"{', '.join(f'{j} (residual {ratio[j]:.1f}× the current noise)' for j in bad)}; above "
            f"{MAX_MISFIT:g}× the gains absorb the mismatch. Check --payload-mass, --frame and --com (where the mass "
            "really is) and that both runs are the same trajectory")
    if not accept:
        raise DataError(text + "; --accept-misfit writes the gains anyway", str(loaded))
    err_console.print(f"[yellow]warning:[/] {text}; written because of --accept-misfit", soft_wrap=True)


def _print(res, missing: list, nominal: bool) -> None:
    from rich.table import Table

    al = res.diagnostics.get("alignment")
    lag = (f", loaded run aligned by a lag of {al['lag_s']:+.3f} s (r = {al['correlation']:.3f})"
           if al and al.get("lag_s") is not None else ", paired row by row")
    t = Table(title=f"drive gains K [N·m/A] (block {res.diagnostics['block_seconds']:.2f} s, "
                    f"{res.diagnostics['n_samples']} samples{lag})")
    for col in ("joint", "K", "± σ", "95 % interval", "offset [A]", "status"):
        t.add_column(col, justify="right")
    for k, j in enumerate(res.joints):
        lo, hi = res.interval[k]
        t.add_row(safe(j), f"{res.gains[k]:.4g}", f"{res.std[k]:.2g}", f"[{lo:.4g}, {hi:.4g}]", f"{res.offset[k]:.3g}",
                  "ok" if res.identified[k] else "[red]misfit[/]" if res.misfit[k] else
                  ("[yellow]nominal[/]" if nominal else "[yellow]weak[/]"))
    console.print(t)
    if missing:
        err_console.print(f"[yellow]warning:[/] not identified (relative σ > 20 % or K ≤ 0): {safe(', '.join(missing))}")

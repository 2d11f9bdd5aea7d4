"""Command: ``sensorless estimate-force`` (the hybrid-force study is ``sensorless experiment hybrid-force``, sensorless-studies)."""

from __future__ import annotations

from pathlib import Path

import typer

from ..errors import SensorlessError
from .common import app, floating_base_option, force_option, guarded, lock_option, model_logs, output_file, path_inputs
from .console import console
from .applied_model import applied_model_options, passive_option, robot_and_model
from .options import ForceReference

__all__ = ["estimate_force"]


@app.command("estimate-force")
@guarded
@applied_model_options(frames=True)
def estimate_force(
    robot: str,
    model: Path | None,
    data: Path = typer.Option(..., help="log with q and measured torque"),
    frame: str = typer.Option(..., help="frame where the force acts (e.g. the tool tip)"),
    reference: ForceReference = typer.Option(ForceReference.local_world_aligned, help="frame of the force"),
    out: Path = typer.Option(..., help="output .npz (t, force, labels, tau_ext, rows, sigma_min, damping, model)"),
    residual: Path | None = typer.Option(None, help="directory of a learned residual (HybridModel.save)"),
    components: str = typer.Option("linear", help="linear (3 forces) | angular | wrench (6) | labels, e.g. fz or "
                                   "fx,fz (a planar leg, whose fy no joint measures)"),
    joints: str | None = typer.Option(None, help="comma-separated joints whose equations are used (default all "
                                      "actuated and passive joints; a floating base's rows always)"),
    sigma_threshold: float = typer.Option(0.01, help="damping starts below this smallest singular value"),
    lambda_max: float = typer.Option(0.02, help="damping at a singularity"),
    lock: list[str] | None = lock_option("joints to lock (default: the model's, settings.robot)"),
    passive: list[str] | None = passive_option(),
    floating_base: bool | None = floating_base_option(),
    force: bool = force_option(),
    plot: bool = typer.Option(True, "--plot/--no-plot", help="write the force against time, unobservable samples "
                              "marked, next to --out as a PNG of the same name (f.npz → f.png)"),
    prep: dict = None,
) -> None:
    """Cartesian force at FRAME from the torque the model (+ residual) does not explain:
    F = (Jᵀ)⁺ (τ_measured − τ_model − τ_residual), damped near singularities, on every equation of known
    generalized force: the actuated joints, and 0 on passive joints and a floating base (a contact model
    is evaluated without its projection). The robot is loaded as the model was identified; without
    --model (or with --model ROBOT.urdf) the description's own parameters are the model (the prior)."""
    import numpy as np

    from ..estimation.force import CartesianForceEstimator
    from ..io import write_npz_atomic
    from ..torque_models import PhysicalModel

    output_file(out, path_inputs(robot, model, data, residual), force)
    figure = _figure_path(out) if plot else None
    if figure is not None:
        output_file(figure, path_inputs(robot, model, data, residual), force)
    r, art = robot_and_model(robot, model, lock=lock, passive=passive, floating=floating_base)
    console.print(f"model: {art.label}", highlight=False, soft_wrap=True)
    phys = PhysicalModel.from_parameters(art.structure, art.parameters)
    (traj,), _ = model_logs(art, [data], r, prep)
    if traj.tau is None:
        raise SensorlessError(f"{data}: the log has no measured torque; force estimation needs it")
    hybrid = None
    if residual is not None:
        from ..learning.models import HybridModel

        hybrid = HybridModel.load(residual, phys)
    est = CartesianForceEstimator(
        r, frame, reference, components=components,
        joints=[j.strip() for j in joints.split(",")] if joints else None,
        sigma_threshold=sigma_threshold, lambda_max=lambda_max,
    )
    res = est.estimate(traj, phys, residual=hybrid)
    _check_observable(res, frame)
    write_npz_atomic(out, **res.arrays(), rows=np.array(est.row_names),
                     model=np.array(art.origin), model_label=np.array(art.label))
    if figure is not None:
        from ..report.force_plot import plot_force

        plot_force(res, figure, title=f"{Path(data).name}: force at {frame}, {art.label.split(':')[0]} model")
    damped = float(np.mean(res.damping > 0))
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nanmean(res.F**2, axis=0))
    unobs = (f"; {res.n_unobservable} sample(s) with an unobservable component (NaN, 'unobservable' in the file)"
             if res.n_unobservable else "")
    console.print(
        f"{len(res.t)} samples; RMS {', '.join(f'{l}={v:.3g} {_unit(l)}' for l, v in zip(res.labels, rms))}; "
        f"damped on {100 * damped:.1f}% of samples{unobs}; wrote {out}" + (f" and {figure}" if figure else "")
    )


def _unit(label: str) -> str:
    """N for a force component (fx, fy, fz), N·m for a moment (mx, my, mz)."""
    return "N·m" if label.startswith("m") else "N"


def _figure_path(out: Path) -> Path:
    """The PNG next to ``--out``: its name with the suffix .png (``_force.png`` if --out is itself a .png)."""
    png = out.with_suffix(".png")
    return png if png != out else out.with_name(out.stem + "_force.png")


def _check_observable(res, frame: str) -> None:
    """Refuse a frame where a force component is unobservable on every sample; warn on some samples."""
    import warnings

    from ..errors import DataWarning, ExcitationError

    never = [lab for lab, u in zip(res.labels, res.unobservable.all(axis=0)) if u] if res.unobservable is not None else []
    if never:
        raise ExcitationError(
            f"frame '{frame}': the force component(s) {', '.join(never)} are unobservable on every sample (the "
            "joints cannot move the frame that way, so no joint torque measures them); choose a frame on a moving "
            "link (sensorless frames lists them) or --components")
    if res.n_unobservable:
        warnings.warn(f"frame '{frame}': {res.n_unobservable} of {len(res.t)} samples have a force component no "
                      "joint torque measures (a singular configuration); written as NaN", DataWarning, stacklevel=2)

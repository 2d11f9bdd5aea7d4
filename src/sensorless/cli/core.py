"""Core commands: identify, predict, demo, benchmark identify."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from ..errors import ExcitationError, SensorlessError
from .common import (
    ROBOT_HELP,
    app,
    atomic_outdir,
    bench_app,
    console,
    err_console,
    guarded,
    load_logs,
    load_robot_arg,
    progress_bar,
)



@app.command()
@guarded
def identify(
    robot: str = typer.Option(..., help=ROBOT_HELP),
    data: List[Path] = typer.Option(..., help="training log(s): .csv .npz .parquet .h5"),
    validate: List[Path] = typer.Option([], help="held-out log(s) to report metrics on"),
    method: str = typer.Option("ols", help="ols | wls | lmi (physically consistent) | svd"),
    prior: Optional[Path] = typer.Option(None, help="lmi: URDF whose inertials are the prior (default: --robot's own)"),
    regularization: str = typer.Option("pullback", help="lmi: pullback | entropic | euclidean | none"),
    gamma: str = typer.Option("auto", help="lmi: regularisation weight, or 'auto' (5-fold cross-validation)"),
    ellipsoids: str = typer.Option("auto", help="lmi: bounding ellipsoids auto | kinematic | none"),
    contain_prior: bool = typer.Option(True, help="lmi: grow each ellipsoid to contain the prior body"),
    out: Path = typer.Option(..., help="output directory (written atomically)"),
    joint_terms: str = typer.Option("fv,fc,offset,armature", help="per-joint terms, comma separated "
                                    "(dvrk_psm: drive set 'authors' (default) or 'motors')"),
    columns: Optional[str] = typer.Option(None, help="column map, e.g. 'q=0:7;v=7:14;tau=14:21' or 'q=pos_{joint}'"),
    rate: Optional[float] = typer.Option(None, help="sample rate [Hz] for logs without a time column"),
    lowpass: Optional[float] = typer.Option(None, help="zero-phase low-pass cut-off [Hz] before identification"),
    savgol_window: Optional[int] = typer.Option(None, help="recompute v, a from q with this Savitzky-Golay window"),
    decimate: int = typer.Option(1, help="keep every n-th sample (after anti-alias filtering)"),
    lock: Optional[List[str]] = typer.Option(None, help="joints to lock (e.g. gripper fingers)"),
    floating_base: Optional[bool] = typer.Option(None, "--floating-base/--fixed-base"),
    contact_frames: Optional[str] = typer.Option(
        None, help="legged robots: comma-separated contact frames (feet); projects out the unknown contact "
                   "forces, flags from the log's 'contact' columns or detected from foot height/speed"),
    contact_dims: Optional[str] = typer.Option(None, help="per contact frame 3 (point foot) or 6 (flat foot); default 3"),
    contact_offset: float = typer.Option(0.0, help="radius [m] of spherical feet (contact point below the frame)"),
    contact_mode: str = typer.Option("projected", help="projected (no force sensing) | wrench (log has contact_forces)"),
    coulomb_smoothing: float = typer.Option(0.0, help="ε [rad/s]: Coulomb term tanh(v/ε) instead of sgn(v); ≈ 2× velocity noise"),
    force: bool = typer.Option(False, help="replace --out if it exists"),
) -> None:
    """Identify a dynamic model from logs; write result.json, model.urdf, joint_terms.json, torques.png."""
    from ..estimators import CADModel
    from ..identification import identify as _identify
    from ..regressor import ModelStructure
    from ..report import metrics_table, plot_torques

    r = load_robot_arg(robot, lock, floating_base)
    with atomic_outdir(out, force) as tmp:
        train = load_logs(data, r, columns, rate, lowpass, savgol_window, decimate)
        val = load_logs(validate, r, columns, rate, lowpass, savgol_window, decimate)
        structure = _structure(r, joint_terms, coulomb_smoothing, contact_frames, contact_dims, contact_offset,
                               contact_mode)
        total = sum(len(t) for t in train)
        with progress_bar() as bar:
            task = bar.add_task("regressor", total=total)
            lmi_kw = _lmi_kwargs(r, structure, method, prior, regularization, gamma, ellipsoids, contain_prior)
            try:
                result = _identify(structure, train, method=method, progress=lambda n: bar.advance(task, n), **lmi_kw)
            except ExcitationError as exc:
                raise ExcitationError(f"{', '.join(map(str, data))}: {exc}") from None
        result.settings.update({"data": [str(p) for p in data], "validate": [str(p) for p in validate],
                                "lowpass_hz": lowpass, "savgol_window": savgol_window, "decimate": decimate,
                                "columns": columns, "rate": rate})
        doc = result.to_dict()
        cad = CADModel(r, like=structure)
        baseline = None
        if method != "ols" and val:
            try:  # unconstrained least squares on the same data, for the comparison table
                baseline = _identify(structure, train, method="ols")
            except SensorlessError:
                baseline = None
        doc["validation"] = {}
        for p, traj in zip(validate, val):
            m_id, m_cad = result.evaluate(traj), cad.score(traj)
            cols = {"CAD": m_cad}
            doc["validation"][str(p)] = {method: m_id.to_dict(), "cad": m_cad.to_dict()}
            if baseline is not None:
                cols["OLS"] = baseline.evaluate(traj)
                doc["validation"][str(p)]["ols"] = cols["OLS"].to_dict()
            cols[method.upper()] = m_id
            console.print(metrics_table(f"held-out {Path(p).name}", cols))
        shown = val[0] if val else train[0]
        plot_torques(shown.t, structure.target(shown), {method.upper(): result.predict(shown), "CAD": cad.predict(shown)},
                     structure.row_names, tmp / "torques.png", title=f"{r.name}: {'held-out' if val else 'training'} torques")
        _export(result, tmp, doc)
        from ..identification.result import write_json_atomic

        write_json_atomic(doc, tmp / "result.json")
    d = result.diagnostics
    extra = (f"γ = {d['gamma']:.3g}, solver {d['lmi']['solver']} ({d['lmi']['status']}), "
             f"all bodies consistent: {d['lmi']['consistent']}" if method == "lmi"
             else f"condition number {d['condition_number']:.1f}")
    console.print(f"{len(result.base.independent)} base parameters, {extra}; wrote {out}/")


def _structure(robot, joint_terms: str, coulomb_smoothing: float, contact_frames, contact_dims, contact_offset,
               contact_mode):
    """ModelStructure, or ContactStructure when contact frames are given."""
    from ..regressor import ModelStructure

    terms = tuple(t for t in joint_terms.split(",") if t)
    if coulomb_smoothing < 0:
        raise SensorlessError(f"--coulomb-smoothing must be ≥ 0, got {coulomb_smoothing}")
    if hasattr(robot, "make_structure"):  # coupled joints (dvrk_psm): drive terms of its own
        if contact_frames:
            raise SensorlessError(f"--contact-frames: '{robot.name}' is a fixed-base coupled-joint model")
        return robot.make_structure(terms, coulomb_smoothing)
    if not contact_frames:
        if contact_dims:
            raise SensorlessError("--contact-dims needs --contact-frames")
        return ModelStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing)
    from ..regressor.contact import ContactStructure

    frames = tuple(f.strip() for f in contact_frames.split(",") if f.strip())
    try:
        dims = tuple(int(d) for d in contact_dims.split(",")) if contact_dims else ()
    except ValueError:
        raise SensorlessError(f"--contact-dims must be comma-separated 3 or 6, got '{contact_dims}'") from None
    return ContactStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing, contact_frames=frames,
                            contact_dims=dims, contact_offset=contact_offset, mode=contact_mode)


def _lmi_kwargs(robot, structure, method, prior, regularization, gamma, ellipsoids, contain_prior) -> dict:
    """Options of `identify(method="lmi")` from the command line."""
    if method != "lmi":
        return {}
    from ..identification import auto_ellipsoids

    if gamma != "auto":
        try:
            gamma = float(gamma)
        except ValueError:
            raise SensorlessError(f"--gamma must be a number or 'auto', got '{gamma}'") from None
    prior_vec = None
    if prior is not None:
        from ..robot import load_robot

        p = load_robot(prior, floating_base=robot.floating_base)
        missing = [b for b in robot.body_names if b not in p.body_names]
        if missing:
            raise SensorlessError(f"{prior}: prior model lacks bodies {missing} of {robot.name}")
        prior_vec = structure.prior()
        pi = p.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(robot.body_names):
            prior_vec[10 * k : 10 * k + 10] = pi[p.body_names.index(b)]
    ell = {"auto": None, "kinematic": "kinematic", "none": False}.get(ellipsoids)
    if ellipsoids not in ("auto", "kinematic", "none"):
        raise SensorlessError(f"--ellipsoids must be auto, kinematic or none, got '{ellipsoids}'")
    if ell is not False and not contain_prior:
        ell = auto_ellipsoids(robot, geometry=None if ell == "kinematic" else "auto", contain_prior=False)
    reg = None if regularization == "none" else regularization
    return {"gamma": gamma, "regularization": reg, "prior": prior_vec, "ellipsoids": ell}


def _export(result, tmp: Path, doc: dict) -> None:
    """URDF + joint terms; a model that is not a physical body is reported, not exported."""
    from ..errors import SensorlessError as _E
    from ..export import write_joint_terms, write_urdf
    from ..parameters import JointTerms, check_physical_consistency

    reports = check_physical_consistency(result.inertial_parameters, list(result.robot.body_names))
    bad = [rep.name for rep in reports if not rep.consistent]
    doc["physical_consistency"] = {"inconsistent_bodies": bad, "n_bodies": len(reports)}
    if hasattr(result.structure, "drive_values"):  # coupled joints: drive terms, no URDF (result.json is the model)
        from ..identification.result import write_json_atomic

        write_json_atomic(result.structure.drive_values(result.parameters), tmp / "drive_terms.json")
        doc["urdf"] = None
        doc["urdf_error"] = f"'{result.robot.name}' has coupled joints; a URDF cannot hold it (result.json does)"
        return
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
@guarded
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
    from ..estimators import load_parameters
    from ..identification.metrics import torque_metrics
    from ..report import metrics_table

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
@guarded
def demo(
    out: Path = typer.Option(Path("demo_output"), help="output directory"),
    seed: int = typer.Option(0, help="random seed"),
) -> None:
    """End-to-end example on a simulated Panda: excite, identify, validate, export."""
    from ..demo import run_demo

    with atomic_outdir(out, force=True) as tmp:
        run_demo(tmp, seed=seed, console=console)
    console.print(f"wrote {out}/")


@bench_app.command("identify")
@guarded
def bench_identify(
    robot: str = typer.Option("panda", help=ROBOT_HELP),
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts"),
    out: Path = typer.Option(Path("benchmarks/results/identify.json")),
) -> None:
    """Identification wall time, peak memory and per-sample cost vs a bare regressor call."""
    from ..bench import bench_identify as run

    res = run(robot, [int(float(s)) for s in samples.split(",")], console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    from ..identification.result import write_json_atomic

    write_json_atomic(res, out)
    console.print(f"wrote {out}")




@bench_app.command("contact")
@guarded
def bench_contact_cmd(
    samples: int = typer.Option(100_000, help="number of Solo12 stance/trot samples"),
    out: Path = typer.Option(Path("benchmarks/results/contact.json")),
) -> None:
    """Contact-projected identification: end-to-end time and projector cost vs a pinv loop."""
    from ..bench import bench_contact
    from ..identification.result import write_json_atomic

    res = bench_contact(samples, console=console)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")


@bench_app.command("lmi")
@guarded
def bench_lmi_cmd(
    robots: str = typer.Option("solo12,talos", help="comma-separated example-robot-data names"),
    solvers: str = typer.Option("CLARABEL,SCS", help="comma-separated cvxpy solver names"),
    out: Path = typer.Option(Path("benchmarks/results/lmi.json")),
) -> None:
    """Setup and solve time of the physically consistent (LMI) program from compressed data."""
    from ..identification.lmi_bench import bench_lmi
    from ..identification.result import write_json_atomic

    res = bench_lmi(robots=tuple(robots.split(",")), solvers=tuple(solvers.split(",")))
    for robot, r in res["results"].items():
        for solver, v in r["solvers"].items():
            console.print(
                f"{robot} ({r['n_bodies']} bodies, {r['n_params']} parameters) {solver}: setup {v.get('setup_seconds', float('nan')):.3f} s, "
                f"solve {v.get('solve_seconds', float('nan')):.3f} s, {v['status']}, consistent {v.get('consistent')}"
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(res, out)
    console.print(f"wrote {out}")

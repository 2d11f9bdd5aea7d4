"""`sensorless benchmark identify | identify-e2e | dask | contact | speed | lmi | peers | real-arm` (JSON output)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import OptionError
from .common import (
    ROBOT_HELP,
    bench_command,
    console,
)
from .options import LinearMethod
from .progress import progress_bars


@bench_command("identify")
def bench_identify(
    robot: str = typer.Option("panda", help=ROBOT_HELP),
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts"),
) -> dict:
    """Identification wall time, peak memory and per-sample cost vs a bare regressor call."""
    from ..benchmarks.identify import bench_identify as run

    return run(robot, [int(float(s)) for s in samples.split(",")], console=console)


@bench_command("identify-e2e", results="identify_e2e")
def bench_identify_e2e_cmd(
    repeats: int = typer.Option(5, help="interleaved rounds (best of; the median is kept too)"),
    long_samples: int = typer.Option(100_000, help="samples of the long UR5 log"),
) -> dict:
    """`sensorless identify` end to end, fresh processes: the UR5 hard case (defaults, --method ols), a long log, `python -c pass`."""
    from ..benchmarks.identify_e2e import bench_identify_e2e

    if min(repeats, long_samples) < 1:
        raise OptionError("--repeats and --long-samples must be >= 1")
    return bench_identify_e2e(repeats=repeats, long_samples=long_samples, console=console)


@bench_command("dask")
def bench_dask_cmd(
    robot: str = typer.Option("panda", help="example-robot-data name"),
    samples: str = typer.Option("1000000,10000000", help="comma-separated total sample counts"),
    samples_per_file: int = typer.Option(100_000, help="samples per generated Parquet file"),
    workers: int = typer.Option(2, help="LocalCluster worker processes (one thread each)"),
    method: LinearMethod = typer.Option(LinearMethod.ols, help="linear least squares: ols or wls"),
) -> dict:
    """Dask LocalCluster vs single-process identification from generated Parquet logs (deleted afterwards)."""
    from ..benchmarks.fleet import bench_dask

    sizes = tuple(int(float(s)) for s in samples.split(","))
    return bench_dask(robot, sizes, samples_per_file=samples_per_file, workers=workers, method=method, console=console)


@bench_command("contact")
def bench_contact_cmd(
    samples: int = typer.Option(100_000, help="number of Solo12 stance/trot samples"),
) -> dict:
    """Contact-projected identification: end-to-end time and projector cost vs a pinv loop."""
    from ..benchmarks.identify import bench_contact

    return bench_contact(samples, console=console)


@bench_command("speed")
def bench_speed_cmd(
    samples: int = typer.Option(100_000, help="samples of the in-memory compression log (UR5 and Panda)"),
    memory_sizes: str = typer.Option("100000,1000000", help="comma-separated sizes of the streamed peak-memory runs"),
    contact_samples: int = typer.Option(100_000, help="Solo12 samples for projector vs pinv loop"),
    identify_samples: int = typer.Option(100_000, help="samples of the UR5 log given to `sensorless identify`"),
    repeats: int = typer.Option(3, help="interleaved repetitions (best of)"),
) -> dict:
    """Compression vs a bare regressor call, peak memory, contact projector vs pinv, CLI start-up and identify."""
    from ..benchmarks.speed import bench_speed

    if min(samples, contact_samples, identify_samples, repeats) < 1:
        raise OptionError("--samples, --contact-samples, --identify-samples and --repeats must be >= 1")
    try:
        sizes = tuple(int(float(x)) for x in memory_sizes.split(","))
    except ValueError:
        raise OptionError(f"--memory-sizes must be comma-separated sample counts, got '{memory_sizes}'") from None
    return bench_speed(n_compress=samples, memory_sizes=sizes, n_contact=contact_samples, n_identify=identify_samples,
                       repeats=repeats, console=console)


@bench_command("lmi")
def bench_lmi_cmd(
    robots: str = typer.Option("solo12,talos", help="comma-separated example-robot-data names"),
    solvers: str = typer.Option("CLARABEL,SCS", help="comma-separated cvxpy solver names"),
) -> dict:
    """Setup and solve time of the physically consistent (LMI) program from compressed data."""
    from ..benchmarks.lmi import bench_lmi

    res = bench_lmi(robots=tuple(robots.split(",")), solvers=tuple(solvers.split(",")))
    for robot, r in res["results"].items():
        for solver, v in r["solvers"].items():
            console.print(
                f"{robot} ({r['n_bodies']} bodies, {r['n_params']} parameters) {solver}: setup {v.get('setup_seconds', float('nan')):.3f} s, "
                f"solve {v.get('solve_seconds', float('nan')):.3f} s, {v['status']}, consistent {v.get('consistent')}"
            )
    return res


@bench_command("peers")
def bench_peers_cmd(
    recipe: Path = typer.Option(Path("benchmarks/peers.toml"), help="fixed recipe (TOML); the built-in copy when "
                                "the default file is absent"),
    seeds: Optional[str] = typer.Option(None, help="comma-separated seeds (default: the recipe's)"),
    cases: Optional[str] = typer.Option(None, help="comma-separated cases (default: all, main,hard)"),
    variants: str = typer.Option("lmi,ols,lmi_unweighted", help="fits: lmi (CLI defaults, --method lmi), ols "
                                 "(--method ols), lmi_unweighted (--method lmi --weights none), lmi_no_contain_prior"),
) -> dict:
    """UR5 accuracy vs figaroh/rigeo's published figures: perturbed-truth inertials, random Fourier
    excitation, 1 % (main) and 5 %/600 samples (hard) noise; `identify` with its CLI defaults
    (--method lmi and ols). Held-out nRMSE vs the noise-free torque, mean and worst over seeds."""
    from ..benchmarks.peers import load_recipe, run_peers

    default = recipe == Path("benchmarks/peers.toml") and not recipe.exists()
    rec = load_recipe(None if default else recipe)
    try:
        seed_list = tuple(int(s) for s in seeds.split(",")) if seeds else None
    except ValueError:
        raise OptionError(f"--seeds must be comma-separated integers, got '{seeds}'") from None
    with progress_bars() as bars:
        res = run_peers(rec, seeds=seed_list, cases=tuple(cases.split(",")) if cases else None,
                        variants=tuple(v for v in variants.split(",") if v), console=console,
                        progress=bars.callback("peer fits (case × seed × variant)"))
    res["recipe"]["file"] = "built-in (sensorless.benchmarks.peers.DEFAULT_RECIPE)" if default else str(recipe)
    for name, c in res["cases"].items():
        peers = ", ".join(f"{k} {v} %" for k, v in rec.peers.get(name, {}).items())
        for v in c:
            if isinstance(c[v], dict) and "mean_nrmse_percent" in c[v]:
                console.print(f"{name:4s} {v:15s} mean {c[v]['mean_nrmse_percent']:.3f} %, worst "
                              f"{c[v]['worst_nrmse_percent']:.3f} %, all bodies consistent: {c[v]['all_consistent']}")
        verdict = {True: "[green]PASS[/]", False: "[red]FAIL[/]", None: "—"}[c["passed"]]
        console.print(f"{name:4s} acceptance (lmi ≤ {c['acceptance_percent']} %, consistent): {verdict}; peers: {peers}")
    return res


@bench_command("real-arm", results="real_arm")
def bench_real_arm_cmd(
    seeds: int = typer.Option(20, help="number of seeds (simulated arms)"),
    seed: int = typer.Option(0, help="first seed"),
    work: Path = typer.Option(Path("sensorless-bench/real_arm_work"), help="folder for the simulated logs and identified models"),
) -> dict:
    """Real-arm acceptance on a simulated UR10 (Stribeck friction, motor currents, jittered 100 Hz, drive
    gains, payload) through the CLI defaults: held-out NRMSE / true model (whole log and motion only),
    idle residual, drive gains and payload per seed (sensorless.benchmarks.real_arm)."""
    from ..benchmarks.real_arm import run

    if seeds < 1:
        raise OptionError("--seeds must be >= 1")
    with progress_bars() as bars:
        res = run(work, seeds=seeds, seed=seed, console=console, progress=bars.callback("simulated arms (seeds)"))
    a = res["acceptance"]
    console.print(f"NRMSE / true model: whole log max {a['nrmse_ratio_max']:.3f} (mean {a['nrmse_ratio_mean']:.3f}), "
                  f"motion only max {a['nrmse_ratio_motion_only_max']:.3f} (mean {a['nrmse_ratio_motion_only_mean']:.3f}); "
                  f"idle/noise max {a['idle_ratio_max']:.2f}; gains max {100 * a['gains_error_max']:.2f} %; "
                  f"payload max {100 * a['payload_error_max']:.2f} %")
    return res

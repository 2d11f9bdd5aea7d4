"""`sensorless benchmark identify | identify-e2e | long-log | dask | contact | speed | lmi | gamma | peers | real-arm |
friction-state` (JSON output)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from sensorless.errors import OptionError
from sensorless.cli.common import ROBOT_HELP
from sensorless.cli.console import console
from sensorless.cli.options import LinearMethod
from sensorless.cli.progress import progress_bars

from .common import bench_command


@bench_command("identify")
def bench_identify(
    robot: str = typer.Option("panda", help=ROBOT_HELP),
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts"),
) -> dict:
    """Identification wall time, peak memory and per-sample cost vs a bare regressor call."""
    from ..benchmarks.identify import bench_identify as run

    return run(robot, [int(float(s)) for s in samples.split(",")], console=console)


@bench_command("long-log")
def bench_long_log_cmd(
    samples: str = typer.Option("100000,1000000", help="comma-separated sample counts of the UR5 logs"),
    repeats: int = typer.Option(1, help="runs per size (the best wall time is kept)"),
    no_plot: bool = typer.Option(False, "--no-plot", help="pass --no-plot to `sensorless identify`"),
    no_stream: bool = typer.Option(False, "--no-stream", help="pass --no-stream (the whole-log path, for comparison)"),
) -> dict:
    """`sensorless identify` (the defaults) on long UR5 logs as fresh processes: wall time, peak RSS,
    µs/sample, against the bare C++ regressor kernel in the same run."""
    from ..benchmarks.long_log import bench_long_log

    sizes = [int(float(s)) for s in samples.split(",")]
    if repeats < 1 or min(sizes) < 1000:
        raise OptionError("--repeats must be >= 1 and every --samples count >= 1000")
    extra = tuple(a for a, on in (("--no-plot", no_plot), ("--no-stream", no_stream)) if on)
    return bench_long_log(sizes, repeats=repeats, extra_args=extra, console=console)


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
    parts: str = typer.Option("compression,memory,contact,startup,identify",
                              help="comma-separated parts to run: compression, memory, contact, startup, identify"),
) -> dict:
    """Compression vs a bare regressor call, peak memory, contact projector vs pinv, CLI start-up and identify."""
    from ..benchmarks.speed import PARTS, bench_speed

    chosen = tuple(p.strip() for p in parts.split(",") if p.strip())
    unknown = sorted(set(chosen) - set(PARTS))
    if unknown or not chosen:
        raise OptionError(f"--parts: unknown part(s) {unknown or [parts]}; choose from {', '.join(PARTS)}")
    if min(samples, contact_samples, identify_samples, repeats) < 1:
        raise OptionError("--samples, --contact-samples, --identify-samples and --repeats must be >= 1")
    try:
        sizes = tuple(int(float(x)) for x in memory_sizes.split(","))
    except ValueError:
        raise OptionError(f"--memory-sizes must be comma-separated sample counts, got '{memory_sizes}'") from None
    return bench_speed(n_compress=samples, memory_sizes=sizes, n_contact=contact_samples, n_identify=identify_samples,
                       repeats=repeats, parts=chosen, console=console)


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


@bench_command("gamma")
def bench_gamma_cmd(
    cases: str = typer.Option("ur5-hard,talos", help="comma-separated: ur5-hard (600-sample UR5 peer case), "
                                                     "talos (the talos-walk example, 33 bodies)"),
    repeats: int = typer.Option(1, help="interleaved repetitions per search (best of)"),
) -> dict:
    """γ selection (`identify --gamma auto`): exhaustive grid vs bracketing search, same run, same γ?"""
    from ..benchmarks.gamma import CASES, bench_gamma

    chosen = [c.strip() for c in cases.split(",") if c.strip()]
    bad = [c for c in chosen if c not in CASES]
    if bad or not chosen:
        raise OptionError(f"--cases: unknown {bad or cases!r}; choose from {', '.join(CASES)}")
    if repeats < 1:
        raise OptionError("--repeats must be >= 1")
    return bench_gamma(chosen, repeats=repeats, console=console)


@bench_command("peers")
def bench_peers_cmd(
    recipe: Path = typer.Option(Path("studies/benchmarks/peers.toml"), help="fixed recipe (TOML); the built-in copy when "
                                "the default file is absent"),
    seeds: Optional[str] = typer.Option(None, help="comma-separated seeds (default: the recipe's)"),
    cases: Optional[str] = typer.Option(None, help="comma-separated cases (default: all, main,hard)"),
    variants: str = typer.Option("lmi,ols,lmi_unweighted", help="`sensorless identify` fits: lmi (CLI defaults), ols "
                                 "(--method ols), lmi_unweighted (--weights none), lmi_no_contain_prior; '' for none"),
    against: str = typer.Option("figaroh,rigeo", help="peers run from their own virtual environments on the same "
                                "data (each skipped, with the reason, when its venv is absent; `make peers`); '' for none"),
    peer_venv: Optional[List[str]] = typer.Option(None, help="NAME=PATH: the virtual environment of peer NAME "
                                                  "(default $XDG_CACHE_HOME/sensorless-peers/NAME, else ~/.cache/...); repeatable"),
    drivers: Optional[Path] = typer.Option(None, help="folder of the peers' driver scripts NAME_driver.py "
                                           "(default: studies/benchmarks/peer_drivers of the source tree)"),
    work: Optional[Path] = typer.Option(None, help="keep the generated logs and every fit's output here "
                                        "(default: a temporary folder, deleted)"),
    timeout: float = typer.Option(600.0, help="seconds allowed to one fit's process"),
) -> dict:
    """UR5 accuracy and wall time side by side: perturbed-truth inertials, random Fourier excitation,
    1 % (main) and 5 %/600 samples (hard) noise; `sensorless identify` (CLI defaults, --method ols) and the
    peers (figaroh, rigeo) from their own venvs, each a fresh process on the same samples, timed from
    process start to its result file. Held-out nRMSE vs the noise-free torque, per-body consistency."""
    from ..benchmarks.peers import load_recipe, run_peers

    default = recipe == Path("studies/benchmarks/peers.toml") and not recipe.exists()
    rec = load_recipe(None if default else recipe)
    try:
        seed_list = tuple(int(s) for s in seeds.split(",")) if seeds else None
    except ValueError:
        raise OptionError(f"--seeds must be comma-separated integers, got '{seeds}'") from None
    venvs = {}
    for item in peer_venv or []:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise OptionError(f"--peer-venv must be NAME=PATH, got '{item}'")
        venvs[name.strip()] = Path(path)
    peers = tuple(p.strip() for p in against.split(",") if p.strip())
    if unknown := sorted(set(venvs) - set(peers)):
        raise OptionError(f"--peer-venv names {unknown} are not in --against '{','.join(peers)}'")
    if timeout <= 0:
        raise OptionError("--timeout must be > 0 seconds")
    with progress_bars() as bars:
        res = run_peers(rec, seeds=seed_list, cases=tuple(cases.split(",")) if cases else None,
                        variants=tuple(v for v in variants.split(",") if v), against=peers, peer_venvs=venvs,
                        drivers=drivers, work=work, timeout=timeout, console=console,
                        progress=bars.callback("fits (case × seed × fit)"))
    res["recipe"]["file"] = "built-in (sensorless_studies.benchmarks.peers.DEFAULT_RECIPE)" if default else str(recipe)
    console.print("case fit             nRMSE mean (worst)     consistent  wall s median (min–max)")
    for name, c in res["cases"].items():
        for k, v in c.items():
            if not isinstance(v, dict):
                continue
            if "skipped" in v:
                console.print(f"{name:4s} {k:15s} skipped: {v['skipped']}")
            elif "mean_nrmse_percent" in v:
                console.print(f"{name:4s} {k:15s} {v['mean_nrmse_percent']:7.3f} % ({v['worst_nrmse_percent']:.3f} %)"
                              f"  {str(v['all_consistent']):10s}  {v['median_seconds']:.2f} ({v['min_seconds']:.2f}–"
                              f"{v['max_seconds']:.2f})" + (f"  [{v['n_errors']} failed]" if v["n_errors"] else ""))
            else:
                console.print(f"{name:4s} {k:15s} every run failed: {v['runs'][0].get('error') if v['runs'] else '?'}")
        verdict = {True: "[green]PASS[/]", False: "[red]FAIL[/]", None: "—"}[c["passed"]]
        console.print(f"{name:4s} accuracy (lmi ≤ {c['acceptance_percent']} %, consistent): {verdict}")
    sp = res["speed"]
    f = lambda x: "—" if x is None else f"{x:.2f} s"  # noqa: E731
    verdict = {True: "[green]PASS[/]", False: "[red]FAIL[/]", None: "—"}[sp["passed"]]
    console.print(f"speed ({sp['case']}, median): defaults {f(sp['defaults_median_seconds'])}, ols "
                  f"{f(sp['ols_median_seconds'])}, fastest peer {sp['fastest_peer'] or '—'} "
                  f"{f(sp['peer_median_seconds'].get(sp['fastest_peer']))} (limits {sp['defaults_seconds']} s, "
                  f"{sp['ols_seconds']} s): {verdict}")
    return res


@bench_command("real-arm", results="real_arm")
def bench_real_arm_cmd(
    seeds: int = typer.Option(20, help="number of seeds (simulated arms)"),
    seed: int = typer.Option(0, help="first seed"),
    work: Path = typer.Option(Path("sensorless-bench/real_arm_work"), help="folder for the simulated logs and identified models"),
) -> dict:
    """Real-arm acceptance on a simulated UR10 (Stribeck friction, motor currents, jittered 100 Hz, drive
    gains, payload) through the CLI defaults: held-out NRMSE / true model (whole log and motion only),
    idle residual, drive gains and payload per seed (sensorless_studies.benchmarks.real_arm)."""
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


@bench_command("friction-state")
def bench_friction_state(
    seeds: int = typer.Option(10, help="random velocity profiles (and noise) per simulated joint"),
) -> dict:
    """Simulated bench joints (LuGre with three stiffness/damping settings, and a static joint): held-out RMSE
    near reversals of the chosen law vs the best static law, and the held-out choice."""
    from ..benchmarks.friction_state import bench_friction_state as run

    if seeds < 1:
        raise OptionError(f"--seeds must be >= 1, got {seeds}")
    res = run(seeds, console=console)
    for name, d in res["truths"].items():
        console.print(f"{name}: state chosen on {d['chosen_state']}/{seeds}; near-reversal RMSE ratio (chosen / best "
                      f"static) median {d['median_ratio_reversals']:.3f}, max {d['max_ratio_reversals']:.3f}")
    return res


@bench_command("calibration")
def bench_calibration_cmd(
    seeds: int = typer.Option(5, help="simulated arms per case"),
    seed: int = typer.Option(0, help="first seed"),
    cases: str = typer.Option(",".join(("clean", "quantized", "flexible", "gain_error", "one_joint", "holding")),
                              help="comma-separated cases (sensorless_studies.benchmarks.calibration)"),
) -> dict:
    """Interval coverage per quantity class (masses, CoM, inertia, joint terms) on simulated UR5 logs carrying
    real artefacts (quantization, rounding, flexibility, gain error, one joint at a time, holding torque)."""
    from ..benchmarks.calibration import CASES, run

    chosen = tuple(c.strip() for c in cases.split(",") if c.strip())
    bad = [c for c in chosen if c not in CASES]
    if seeds < 1 or bad or not chosen:
        raise OptionError(f"--seeds must be >= 1 and --cases among {', '.join(CASES)}" + (f" (got {bad})" if bad else ""))
    with progress_bars() as bars:
        return run(chosen, seeds=seeds, seed=seed, console=console, progress=bars.callback("calibration (case × seed)"))

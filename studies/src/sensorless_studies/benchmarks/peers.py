"""`sensorless benchmark peers`: the UR5 comparison with figaroh and rigeo, from generated data.

Fixed recipe (``studies/benchmarks/peers.toml``, :data:`DEFAULT_RECIPE`), per seed ``s``:

* robot: UR5 from example-robot-data (6 bodies);
* truth: every body with mass perturbed as ``m·exp(N(0, 0.1))``, CoM ``+ N(0, 2 cm)`` per
  axis, principal moments of the inertia about the CoM ``× exp(N(0, 0.2))`` (redrawn until
  they satisfy the triangle inequalities, so the truth is a physical body) and principal
  axes rotated by ``exp([ω]×)``, ``ω ~ N(0, 0.2 rad)`` per axis; no friction, no armature;
* excitation: 5-harmonic Fourier series at 0.1 Hz (:func:`~sensorless.excitation.random_fourier`,
  random coefficients scaled into the limits) sampled at 100 Hz, training and held-out
  trajectories drawn with different seeds;
* torques: RNEA on the truth, plus Gaussian noise of ``level × std_j(τ_train)`` per joint;
* metric: on the held-out trajectory, ``RMSE_j(τ̂ − τ_true) / std_j(τ_true)`` against the
  noise-free torque, mean over joints, in %.

Cases: "main" (1 % noise, 2000 samples) and "hard" (5 % noise, 600 samples). Each case is given,
as the same training samples (q, q̇, q̈, τ), to ``sensorless identify`` with every option at its
command-line default ("lmi"), ``--method ols`` and, for reference, ``--weights none``, each a fresh
process timed from its start to its ``result.json``; and, with ``--against figaroh,rigeo``, to the
peers run from their own virtual environments (:mod:`.peer_runs`, ``make peers``), timed the same
way. Every fit is scored on our side: held-out nRMSE of τ̂ = W π and per-body consistency of π.
"""

from __future__ import annotations

import platform
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pinocchio as pin

from sensorless.data.trajectory import Trajectory
from sensorless.errors import OptionError
from sensorless.excitation import random_fourier
from sensorless.robot import Robot, load_robot
from sensorless.testing import TruthModel, map_body_inertias, synthetic_trajectory

__all__ = [
    "DEFAULT_RECIPE",
    "VARIANTS",
    "CaseSpec",
    "PeerCase",
    "InertialPerturbation",
    "Recipe",
    "cli_defaults",
    "load_recipe",
    "peer_case",
    "perturb_inertials",
    "run_peers",
]


@dataclass(frozen=True)
class CaseSpec:
    noise: float  # fraction of the per-joint torque std
    train_samples: int
    acceptance_percent: float | None = None


@dataclass(frozen=True)
class InertialPerturbation:
    """How the truth's inertials are drawn from the URDF's (the recipe's ``[perturbation]``):
    mass ``m·exp(N(0, mass_log_sigma))``, CoM ``+ N(0, com_sigma)`` per axis, principal moments
    about the CoM ``λ·exp(N(0, moment_log_sigma))`` (redrawn, up to 100 times, then left
    unscaled, until ``λ_i ≤ λ_j + λ_k``), principal axes ``R·exp([ω]×)``, ``ω ~ N(0, axis_sigma)``."""

    mass_log_sigma: float = 0.1
    com_sigma: float = 0.02
    moment_log_sigma: float = 0.2
    axis_sigma: float = 0.2


@dataclass(frozen=True)
class Recipe:
    """The benchmark's fixed recipe (``studies/benchmarks/peers.toml``)."""

    robot: str = "ur5"
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    harmonics: int = 5
    base_freq: float = 0.1
    rate: float = 100.0
    test_samples: int = 2000
    perturbation: InertialPerturbation = InertialPerturbation()
    cases: dict[str, CaseSpec] = field(default_factory=lambda: {
        "main": CaseSpec(noise=0.01, train_samples=2000, acceptance_percent=0.53),
        "hard": CaseSpec(noise=0.05, train_samples=600, acceptance_percent=8.0),
    })
    speed: dict[str, Any] = field(default_factory=lambda: {"case": "hard", "defaults_seconds": 1.5, "ols_seconds": 1.0})
    peers: dict[str, Any] = field(default_factory=lambda: {
        "source": "side-by-side run quoted in issue #13 (figaroh 1.0.2, rigeo 0.2.0)",
        "main": {"figaroh_1.0.2": 0.53, "rigeo_0.2.0": 0.53},
        "hard": {"rigeo_0.2.0_box": 8.36},
    })


DEFAULT_RECIPE = Recipe()


def load_recipe(path: str | Path | None) -> Recipe:
    """The recipe from a TOML file (keys as :class:`Recipe`, cases under ``[cases.NAME]``,
    the perturbation under ``[perturbation]``); None: :data:`DEFAULT_RECIPE`."""
    if path is None:
        return DEFAULT_RECIPE
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise OptionError(f"--recipe {path}: cannot read the recipe ({exc})") from None
    try:
        pert = InertialPerturbation(**doc.pop("perturbation", {}))
        cases = {k: CaseSpec(**v) for k, v in doc.pop("cases").items()}
        doc["seeds"] = tuple(int(x) for x in doc.get("seeds", DEFAULT_RECIPE.seeds))
        return Recipe(**doc, perturbation=pert, cases=cases)
    except (TypeError, KeyError, ValueError) as exc:
        raise OptionError(f"--recipe {path}: bad recipe ({exc}); see studies/benchmarks/peers.toml") from None


def perturb_inertials(
    robot: Robot,
    rng: np.random.Generator | int = 0,
    perturbation: InertialPerturbation = InertialPerturbation(),
) -> Robot:
    """A copy of ``robot`` with every body's inertials drawn as :class:`InertialPerturbation` says."""
    rng = np.random.default_rng(rng)
    p = perturbation

    def perturbed(I: pin.Inertia) -> pin.Inertia:
        m = I.mass * float(np.exp(rng.normal(0.0, p.mass_log_sigma)))
        c = np.asarray(I.lever) + rng.normal(0.0, p.com_sigma, 3)
        lam, R = np.linalg.eigh(np.asarray(I.inertia))
        for _ in range(100):
            lam2 = lam * np.exp(rng.normal(0.0, p.moment_log_sigma, 3))
            if np.all(lam2 <= lam2.sum() - lam2):  # triangle inequalities: a real body
                break
        else:
            lam2 = lam
        R2 = R @ pin.exp3(rng.normal(0.0, p.axis_sigma, 3))
        Ic = (R2 * lam2) @ R2.T
        return pin.Inertia(m, c, 0.5 * (Ic + Ic.T))

    return map_body_inertias(robot, perturbed)


@dataclass
class PeerCase:
    """One generated case: the truth, a noisy training log and a noise-free held-out log."""

    name: str
    seed: int
    truth: TruthModel
    train: Trajectory
    test: Trajectory  # torques without noise
    noise_std: np.ndarray


def _zero_terms(robot: Robot) -> TruthModel:
    z = np.zeros(robot.n_actuated)
    return TruthModel(robot, z, z.copy(), z.copy(), z.copy())


def peer_case(name: str, seed: int, robot: Robot | None = None, recipe: Recipe = DEFAULT_RECIPE,
              train_samples: int | None = None) -> PeerCase:
    """Generate case ``name`` of ``recipe`` for ``seed`` (seeds: truth 1000 s, training
    excitation 1000 s + 1, held-out excitation + 2, noise + 3). ``train_samples`` overrides
    the case's (the reduced test case)."""
    spec = recipe.cases[name]
    robot = load_robot(recipe.robot) if robot is None else robot
    n_train = spec.train_samples if train_samples is None else int(train_samples)
    base = 1000 * int(seed)
    truth = _zero_terms(perturb_inertials(robot, base, recipe.perturbation))
    exc_train = random_fourier(robot, harmonics=recipe.harmonics, base_freq=recipe.base_freq, rng=base + 1)
    exc_test = random_fourier(robot, harmonics=recipe.harmonics, base_freq=recipe.base_freq, rng=base + 2)
    clean = synthetic_trajectory(truth, exc_train.sample(recipe.rate, n_train / recipe.rate))
    sigma = spec.noise * clean.tau.std(axis=0)
    rng = np.random.default_rng(base + 3)
    train = clean.with_(tau=clean.tau + rng.normal(size=clean.tau.shape) * sigma)
    test = synthetic_trajectory(truth, exc_test.sample(recipe.rate, recipe.test_samples / recipe.rate))
    return PeerCase(name, int(seed), truth, train, test, sigma)


def cli_defaults() -> dict[str, Any]:
    """The default value of every option of ``sensorless identify``: the fields of
    :class:`sensorless.run.RunConfig` (the command's options are built from them)."""
    from sensorless.run import RunConfig

    return RunConfig().options()


#: fits of `sensorless identify` the benchmark runs (name: extra command-line flags; "lmi" = the defaults)
VARIANTS: dict[str, tuple[str, ...]] = {
    "lmi": (),  # the CLI defaults (--method lmi)
    "ols": ("--method", "ols"),
    "lmi_unweighted": ("--weights", "none"),  # reference: the pre-issue-13 weighting
    "lmi_no_contain_prior": ("--no-contain-prior",),  # geometry-only ellipsoids (warns)
}
DEFAULT_VARIANTS = ("lmi", "ols", "lmi_unweighted")


def _summary(rs: list[dict], skipped: str | None = None) -> dict:
    """Mean/worst nRMSE, consistency and wall times (median, min, max) over the runs without error."""
    if skipped is not None:
        return {"skipped": skipped, "runs": []}
    ok = [r for r in rs if "error" not in r]
    out: dict[str, Any] = {"n_runs": len(rs), "n_errors": len(rs) - len(ok), "runs": rs}
    if ok:
        e, t = np.array([r["nrmse_percent"] for r in ok]), np.array([r["seconds"] for r in ok])
        out.update(mean_nrmse_percent=float(e.mean()), worst_nrmse_percent=float(e.max()),
                   all_consistent=all(r["all_consistent"] for r in ok), median_seconds=float(np.median(t)),
                   min_seconds=float(t.min()), max_seconds=float(t.max()))
    return out


def _speed_verdict(recipe: Recipe, cases: dict, against: tuple[str, ...]) -> dict:
    """Issue #28: on ``recipe.speed["case"]``, the defaults' median wall time (process start to
    result.json) against the faster peer's median in the same run and the absolute limits."""
    sp = recipe.speed
    c = cases.get(sp["case"], {})
    median = {k: v.get("median_seconds") for k, v in c.items() if isinstance(v, dict)}
    peers = {p: median.get(p) for p in against if median.get(p) is not None}
    fastest = min(peers, key=peers.get) if peers else None
    d, o = median.get("lmi"), median.get("ols")
    checks = {"defaults_le_fastest_peer": None if d is None or fastest is None else bool(d <= peers[fastest]),
              "defaults_le_limit": None if d is None else bool(d <= sp["defaults_seconds"]),
              "ols_le_limit": None if o is None else bool(o <= sp["ols_seconds"])}
    known = [v for v in checks.values() if v is not None]
    return {**sp, "defaults_median_seconds": d, "ols_median_seconds": o, "peer_median_seconds": peers,
            "fastest_peer": fastest, "defaults_over_fastest_peer": None if d is None or fastest is None
            else d / peers[fastest], **checks, "passed": all(known) if len(known) == len(checks) else None}


def run_peers(
    recipe: Recipe = DEFAULT_RECIPE,
    *,
    seeds: tuple[int, ...] | None = None,
    cases: tuple[str, ...] | None = None,
    variants: tuple[str, ...] = DEFAULT_VARIANTS,
    against: tuple[str, ...] = (),
    peer_venvs: dict[str, str | Path] | None = None,
    drivers: str | Path | None = None,
    work: str | Path | None = None,
    train_samples: int | None = None,
    timeout: float = 600.0,
    console=None,
    log: Callable[[str], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Run the recipe: per case × seed, one generated case given to every fit, each a separate process
    timed from its start to its result file (:mod:`.peer_runs`): ``sensorless identify`` per variant,
    then each peer in ``against`` from its venv (``peer_venvs[name]``, default
    :func:`~.peer_runs.default_venv`) with its driver in ``drivers``. Per case and fit: mean and worst
    nRMSE over seeds, consistency of every body in every run, wall times; the acceptance verdict of
    "lmi" (mean and worst ≤ the case's ``acceptance_percent``, all consistent) and the speed verdict
    (:func:`_speed_verdict`). A peer without venv or driver is skipped with the reason, a failing fit
    is recorded with its error. ``work``: keep the logs and outputs there (default: a temporary
    folder, deleted). ``progress(done, total)`` after each fit."""
    import os
    import tempfile

    from .peer_runs import default_drivers, default_venv, peer_skip_reason, run_identify, run_peer, write_case

    say = log or (console.print if console is not None else (lambda _m: None))
    seeds = recipe.seeds if seeds is None else tuple(seeds)
    cases = tuple(recipe.cases) if cases is None else tuple(cases)
    unknown = [c for c in cases if c not in recipe.cases] + [v for v in variants if v not in VARIANTS]
    if unknown:
        raise OptionError(f"unknown case(s)/variant(s) {unknown}; cases {list(recipe.cases)}, variants {list(VARIANTS)}")
    venvs = {p: Path(peer_venvs[p]) if peer_venvs and p in peer_venvs else default_venv(p) for p in against}
    drivers = default_drivers() if drivers is None else Path(drivers)
    skipped = {p: peer_skip_reason(p, venvs[p], drivers) for p in against}
    live = [p for p in against if skipped[p] is None]
    for p in against:
        if skipped[p]:
            say(f"{p}: skipped, {skipped[p]}")
    robot = load_robot(recipe.robot)
    out: dict[str, Any] = {
        "recipe": {**{k: v for k, v in asdict(recipe).items() if k != "peers"}, "seeds": list(seeds),
                   **({"train_samples_override": train_samples} if train_samples else {})},
        "cli_defaults": {k: v for k, v in cli_defaults().items() if isinstance(v, (str, int, float, bool))},
        "variants": {v: ["sensorless", "identify", "--robot", recipe.robot, "--data", "LOG", "--out", "DIR", "--force",
                         *VARIANTS[v]] for v in variants},
        "against": {p: {"venv": str(venvs[p]), "driver": str(drivers / f"{p}_driver.py"), "skipped": skipped[p]}
                    for p in against},
        "published": recipe.peers,
        "timing": "seconds: process start to its result file (result.json / the driver's OUT); fits run one "
                  "after another, interleaved per seed",
        "cases": {},
        "machine": {"platform": platform.platform(), "python": platform.python_version(),
                    "pinocchio": pin.__version__, "cpus": os.cpu_count(), "load_average_before": os.getloadavg(),
                    "thread_env": {k: os.environ[k] for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                              "MKL_NUM_THREADS") if k in os.environ}},
    }
    done, total = 0, len(cases) * len(seeds) * (len(variants) + len(live))
    with tempfile.TemporaryDirectory(prefix="sensorless-peers-") as tmp:
        root = Path(work) if work is not None else Path(tmp)
        for name in cases:
            runs: dict[str, list] = {v: [] for v in (*variants, *against)}
            for seed in seeds:
                case = peer_case(name, seed, robot, recipe, train_samples)
                folder = root / name / f"seed{seed}"
                case_file, log_file = write_case(folder, case, robot)
                fits = [(v, lambda v=v: run_identify(log_file, folder / v, robot, recipe.robot, case,
                                                     list(VARIANTS[v]), timeout)) for v in variants]
                fits += [(p, lambda p=p: run_peer(p, venvs[p], drivers, case_file, folder / f"{p}.npz", robot,
                                                  case, timeout)) for p in live]
                for key, fit in fits:
                    r = {"seed": seed, **fit()}
                    runs[key].append(r)
                    done += 1
                    if progress is not None:
                        progress(done, total)
                    say(f"{name} seed {seed} {key:15s} " + (f"error: {r['error']}" if "error" in r else
                        f"nRMSE {r['nrmse_percent']:.3f} %  consistent {r['all_consistent']}  {r['seconds']:.2f} s"
                        + (f"  γ {r['gamma']:.3g}" if r.get("gamma") is not None else "")))
            summary = {k: _summary(rs, skipped.get(k)) for k, rs in runs.items()}
            limit = recipe.cases[name].acceptance_percent
            lmi = summary.get("lmi", {})
            out["cases"][name] = {
                **summary,
                "acceptance_percent": limit,
                "passed": None if "mean_nrmse_percent" not in lmi or limit is None else
                bool(lmi["mean_nrmse_percent"] <= limit and lmi["worst_nrmse_percent"] <= limit
                     and lmi["all_consistent"] and lmi["n_errors"] == 0),
            }
    out["speed"] = _speed_verdict(recipe, out["cases"], against)
    out["machine"]["load_average_after"] = os.getloadavg()
    return out

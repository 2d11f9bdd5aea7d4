"""`sensorless benchmark peers`: the UR5 comparison with figaroh and rigeo, from generated data.

Fixed recipe (``benchmarks/peers.toml``, :data:`DEFAULT_RECIPE`), per seed ``s``:

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

Cases: "main" (1 % noise, 2000 samples) and "hard" (5 % noise, 600 samples). Each is fitted
by ``sensorless identify --method lmi`` and ``--method ols`` with every other option at its
command-line default (read from the command's signature, so the benchmark follows the
defaults), and, for reference, LMI with ``--weights none``.
"""

from __future__ import annotations

import inspect
import platform
import time
import tomllib
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pinocchio as pin

from ..data.trajectory import Trajectory
from ..errors import OptionError
from ..excitation import random_fourier
from ..parameters import check_physical_consistency
from ..robot import Robot, load_robot
from ..simulation import TruthModel, map_body_inertias, synthetic_trajectory

__all__ = [
    "DEFAULT_RECIPE",
    "VARIANTS",
    "CaseSpec",
    "PeerCase",
    "InertialPerturbation",
    "Recipe",
    "cli_defaults",
    "held_out_nrmse",
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
    """The benchmark's fixed recipe (``benchmarks/peers.toml``)."""

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
        raise OptionError(f"--recipe {path}: bad recipe ({exc}); see benchmarks/peers.toml") from None


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


def held_out_nrmse(pred: np.ndarray, case: PeerCase) -> np.ndarray:
    """Per-joint ``RMSE(τ̂ − τ_true) / std(τ_true)`` on the held-out log, in %."""
    tau = case.test.tau
    return 100.0 * np.sqrt(np.mean((pred - tau) ** 2, axis=0)) / tau.std(axis=0)


def cli_defaults() -> dict[str, Any]:
    """The default value of every option of ``sensorless identify`` (from its signature)."""
    from ..cli.identify import identify as command

    fn = inspect.unwrap(command)
    out = {}
    for name, p in inspect.signature(fn).parameters.items():
        d = p.default
        out[name] = getattr(d, "default", d)
    return out


def _fit(case: PeerCase, robot: Robot, method: str, overrides: dict[str, Any] | None = None):
    """``sensorless identify --method METHOD`` with the command-line defaults (plus
    ``overrides``), in process on the generated logs: the same option handling
    (``_structure``, ``_lmi_kwargs``, ``weights_option``) and the same ``identify`` call."""
    from ..cli.identify_model import _friction_options, _lmi_kwargs, _structure
    from ..identification.friction import identify_friction
    from ..identification import identify
    from ..identification.weights import weights_option

    o = {**cli_defaults(), **(overrides or {}), "method": method}
    eps, vs = _friction_options(o["coulomb_smoothing"], o["stribeck_velocity"])
    structure = _structure(robot, o["joint_terms"], 0.0 if eps == "auto" else eps, None, None, 0.0, o["contact_mode"])
    lmi_kw = _lmi_kwargs(robot, structure, method, None, o["regularization"], o["gamma"], o["ellipsoids"],
                         o["contain_prior"])
    weights = weights_option(o["weights"], structure.row_names)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kw = dict(method=method, weights=weights, outliers=o["outliers"], **lmi_kw)
        if eps == "auto" or "stribeck" in structure.joint_terms:  # what `identify` does for plain arms
            res, _ = identify_friction(structure, [case.train], coulomb_smoothing=eps, stribeck_velocity=vs,
                                       identify_kwargs=kw)
        else:
            res = identify(structure, [case.train], **kw)
    seconds = time.perf_counter() - t0
    e = held_out_nrmse(res.predict(case.test), case)
    reports = check_physical_consistency(res.inertial_parameters, list(robot.body_names))
    d = res.diagnostics
    return {
        "nrmse_percent": float(e.mean()),
        "nrmse_percent_per_joint": dict(zip(structure.row_names, map(float, e))),
        "consistent_bodies": {r.name: bool(r.consistent) for r in reports},
        "all_consistent": all(r.consistent for r in reports),
        "stribeck_joints": [j for j in robot.actuated_joints if "stribeck" in res.structure.terms_of(j)],
        "gamma": d.get("gamma"),
        "gamma_edge": (d.get("gamma_selection") or {}).get("edge"),
        "seconds": seconds,
        "warnings": [str(w.message) for w in caught],
    }


VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "lmi": ("lmi", {}),  # the CLI defaults with --method lmi
    "ols": ("ols", {}),
    "lmi_unweighted": ("lmi", {"weights": "none"}),  # reference: the pre-issue-13 weighting
    "lmi_no_contain_prior": ("lmi", {"contain_prior": False}),  # geometry-only ellipsoids (warns)
}
DEFAULT_VARIANTS = ("lmi", "ols", "lmi_unweighted")


def run_peers(
    recipe: Recipe = DEFAULT_RECIPE,
    *,
    seeds: tuple[int, ...] | None = None,
    cases: tuple[str, ...] | None = None,
    variants: tuple[str, ...] = DEFAULT_VARIANTS,
    train_samples: int | None = None,
    console=None,
    log: Callable[[str], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Run the recipe: every case × seed × variant; per case the mean and worst nRMSE over
    seeds, whether every body was consistent in every run, and the acceptance verdict of the
    "lmi" variant (mean over seeds ≤ the case's ``acceptance_percent`` and all consistent).
    ``progress(done, total)`` after each fit."""
    say = log or (console.print if console is not None else (lambda _m: None))
    seeds = recipe.seeds if seeds is None else tuple(seeds)
    cases = tuple(recipe.cases) if cases is None else tuple(cases)
    unknown = [c for c in cases if c not in recipe.cases] + [v for v in variants if v not in VARIANTS]
    if unknown:
        raise OptionError(f"unknown case(s)/variant(s) {unknown}; cases {list(recipe.cases)}, variants {list(VARIANTS)}")
    robot = load_robot(recipe.robot)
    out: dict[str, Any] = {
        "recipe": {**{k: v for k, v in asdict(recipe).items() if k != "peers"}, "seeds": list(seeds),
                   **({"train_samples_override": train_samples} if train_samples else {})},
        "cli_defaults": {k: v for k, v in cli_defaults().items() if isinstance(v, (str, int, float, bool))},
        "peers": recipe.peers,
        "cases": {},
        "machine": {"platform": platform.platform(), "python": platform.python_version(),
                    "pinocchio": pin.__version__},
    }
    done, total = 0, len(cases) * len(seeds) * len(variants)
    for name in cases:
        runs: dict[str, list] = {v: [] for v in variants}
        for seed in seeds:
            case = peer_case(name, seed, robot, recipe, train_samples)
            for v in variants:
                method, overrides = VARIANTS[v]
                r = _fit(case, robot, method, overrides)
                runs[v].append({"seed": seed, **r})
                done += 1
                if progress is not None:
                    progress(done, total)
                say(f"{name} seed {seed} {v:15s} nRMSE {r['nrmse_percent']:.3f} %  consistent {r['all_consistent']}"
                    + (f"  γ {r['gamma']:.3g}" if r["gamma"] is not None else "") + f"  ({r['seconds']:.1f} s)")
        summary = {}
        for v, rs in runs.items():
            e = np.array([r["nrmse_percent"] for r in rs])
            summary[v] = {"mean_nrmse_percent": float(e.mean()), "worst_nrmse_percent": float(e.max()),
                          "all_consistent": all(r["all_consistent"] for r in rs), "runs": rs}
        limit = recipe.cases[name].acceptance_percent
        lmi = summary.get("lmi")
        out["cases"][name] = {
            **summary,
            "acceptance_percent": limit,
            "passed": None if lmi is None or limit is None else
            bool(lmi["mean_nrmse_percent"] <= limit and lmi["worst_nrmse_percent"] <= limit and lmi["all_consistent"]),
        }
    return out

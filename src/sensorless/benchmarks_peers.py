"""`sensorless benchmark peers`: the UR5 comparison with figaroh and rigeo, from generated data.

Fixed recipe (benchmarks/README.md), per seed ``s``:

* robot: UR5 from example-robot-data (6 bodies);
* truth: every body with mass perturbed as ``m·exp(N(0, 0.1))``, CoM ``+ N(0, 2 cm)`` per
  axis, principal moments of the inertia about the CoM ``× exp(N(0, 0.2))`` (redrawn until
  they satisfy the triangle inequalities, so the truth is a physical body) and principal
  axes rotated by ``exp([ω]×)``, ``ω ~ N(0, 0.2 rad)`` per axis; no friction, no armature;
* excitation: 5-harmonic Fourier series at 0.1 Hz (:func:`~sensorless.excitation.random_fourier`,
  random coefficients scaled into the limits), training and held-out trajectories drawn
  with different seeds;
* torques: RNEA on the truth, plus Gaussian noise of ``level × std_j(τ_train)`` per joint;
* metric: on the held-out trajectory, ``RMSE_j(τ̂ − τ_true) / std_j(τ_true)`` against the
  noise-free torque, mean over joints, in %.

Cases: "main" (1 % noise, :data:`CASES`) and "hard" (5 % noise, 600 samples).
"""

from __future__ import annotations

import platform
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin

from .data.trajectory import Trajectory
from .excitation import random_fourier
from .robot import Robot, load_robot
from .simulation import TruthModel, synthetic_trajectory

__all__ = ["CASES", "PEER_FIGURES", "PeerCase", "peer_case", "perturb_inertials", "run_peers", "held_out_nrmse"]


@dataclass(frozen=True)
class CaseSpec:
    noise: float  # fraction of the per-joint torque std
    rate: float  # Hz
    train_samples: int
    test_samples: int


CASES: dict[str, CaseSpec] = {
    "main": CaseSpec(noise=0.01, rate=100.0, train_samples=2000, test_samples=2000),
    "hard": CaseSpec(noise=0.05, rate=100.0, train_samples=600, test_samples=2000),
}
HARMONICS, BASE_FREQ = 5, 0.1
# Published by the side-by-side run reported in issue 13 (figaroh 1.0.2 and rigeo 0.2.0).
PEER_FIGURES = {
    "source": "side-by-side run reported in issue 13: figaroh 1.0.2 and rigeo 0.2.0",
    "main": {"peers_mean_nrmse_percent": 0.53},
    "hard": {"rigeo_box_realisability_nrmse_percent": 8.36},
}


def perturb_inertials(
    robot: Robot,
    rng: np.random.Generator | int = 0,
    *,
    mass_sigma: float = 0.1,
    com_sigma: float = 0.02,
    moment_sigma: float = 0.2,
    axis_sigma: float = 0.2,
) -> Robot:
    """A copy of ``robot`` with the recipe's perturbed inertials (module docstring).

    Principal moments ``λ`` of the inertia about the CoM become ``λ·exp(N(0, moment_sigma))``,
    redrawn (up to 100 times, then left unscaled) until ``λ_i ≤ λ_j + λ_k``; the principal
    axes ``R`` become ``R·exp([ω]×)``, ``ω ~ N(0, axis_sigma)``.
    """
    rng = np.random.default_rng(rng)
    model = robot.model.copy()
    for j in range(1, model.njoints):
        I = model.inertias[j]
        if I.mass <= 0:
            continue
        m = I.mass * float(np.exp(rng.normal(0.0, mass_sigma)))
        c = np.asarray(I.lever) + rng.normal(0.0, com_sigma, 3)
        lam, R = np.linalg.eigh(np.asarray(I.inertia))
        for _ in range(100):
            lam2 = lam * np.exp(rng.normal(0.0, moment_sigma, 3))
            if np.all(lam2 <= lam2.sum() - lam2):  # triangle inequalities: a real body
                break
        else:
            lam2 = lam
        R2 = R @ pin.exp3(rng.normal(0.0, axis_sigma, 3))
        Ic = (R2 * lam2) @ R2.T
        model.inertias[j] = pin.Inertia(m, c, 0.5 * (Ic + Ic.T))
    return Robot(model, name=robot.name + "_truth", source=robot.source, actuated_joints=robot.actuated_joints)


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


def peer_case(name: str, seed: int, robot: Robot | None = None) -> PeerCase:
    """Generate case ``name`` ("main" | "hard") for ``seed`` (seeds: truth 1000 s + 0, training
    excitation + 1, held-out excitation + 2, noise + 3)."""
    spec = CASES[name]
    robot = load_robot("ur5") if robot is None else robot
    base = 1000 * int(seed)
    truth = _zero_terms(perturb_inertials(robot, base))
    exc_train = random_fourier(robot, harmonics=HARMONICS, base_freq=BASE_FREQ, rng=base + 1)
    exc_test = random_fourier(robot, harmonics=HARMONICS, base_freq=BASE_FREQ, rng=base + 2)
    clean = synthetic_trajectory(truth, exc_train.sample(spec.rate, spec.train_samples / spec.rate))
    sigma = spec.noise * clean.tau.std(axis=0)
    rng = np.random.default_rng(base + 3)
    train = clean.with_(tau=clean.tau + rng.normal(size=clean.tau.shape) * sigma)
    test = synthetic_trajectory(truth, exc_test.sample(spec.rate, spec.test_samples / spec.rate))
    return PeerCase(name, int(seed), truth, train, test, sigma)


def held_out_nrmse(pred: np.ndarray, case: PeerCase) -> np.ndarray:
    """Per-joint ``RMSE(τ̂ − τ_true) / std(τ_true)`` on the held-out log, in %."""
    tau = case.test.tau
    return 100.0 * np.sqrt(np.mean((pred - tau) ** 2, axis=0)) / tau.std(axis=0)

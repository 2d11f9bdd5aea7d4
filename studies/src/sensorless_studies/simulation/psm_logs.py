"""Simulated dVRK PSM logs (motor coordinates) with known ground truth: a random physically
consistent "true" PSM, excitation motions within the PSM limits, and the efforts of a force at
the tool tip.

Efforts are inverse dynamics of the replayed motion (a position-controlled replay), so no
forward simulation is needed: τ_θ = W(θ, θ̇, θ̈) π + Gᵀ J_tipᵀ (−F) … with F the force the tip
exerts on the environment (the sign convention of ``estimate-force``: τ_ext = Jᵀ F).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sensorless.data import Trajectory
from sensorless.robots import psm_structure

__all__ = ["palpation_force", "psm_motion", "psm_truth", "tip_force_efforts"]


def psm_truth(rng: np.random.Generator, coulomb_smoothing: float = 0.05):
    """(structure, parameters) of a physically consistent "true" PSM: random masses, CoMs and
    inertias on the authors' bodies, small drive terms."""
    s = psm_structure(coulomb_smoothing=coulomb_smoothing)
    p = np.zeros(s.n_params)
    for k in range(s.robot.n_bodies):
        p[10 * k : 10 * k + 10] = pin.Inertia(rng.uniform(0.2, 1.0), rng.uniform(-0.1, 0.1, 3),
                                               np.diag(rng.uniform(1e-3, 1e-2, 3))).toDynamicParameters()
    p[s.n_body_params :] = rng.normal(size=s.n_params - s.n_body_params) * 0.01
    return s, p


def psm_motion(seed: int = 1, duration: float = 20.0, rate: float = 100.0) -> Trajectory:
    """A random Fourier excitation of the PSM coordinates (4 harmonics of 0.2 Hz) within its limits."""
    from sensorless.excitation import random_fourier

    return random_fourier(psm_structure().robot, rng=seed, base_freq=0.2, harmonics=4).sample(rate, duration)


def tip_force_efforts(structure, motion: Trajectory, force: np.ndarray, frame: str = "tool_tip") -> np.ndarray:
    """Coordinate efforts (N, 7) the drives add when the tip pushes on the environment with
    ``force`` (N, 3; world axes): Gᵀ [RNEA(q, 0, 0, f_ext) − RNEA(q, 0, 0)] with f_ext = −F at ``frame``."""
    model = structure.tree.model
    data = model.createData()
    fid = structure.tree.frame_id(frame)
    fr = model.frames[fid]
    z = np.zeros(model.nv)
    out = np.empty((len(motion), structure.G.shape[1]))
    for k, (q, f) in enumerate(zip(structure.joint_values(motion.q), np.asarray(force, float))):
        pin.framesForwardKinematics(model, data, q)
        R = data.oMf[fid].rotation
        fext = [pin.Force.Zero() for _ in range(model.njoints)]
        fext[fr.parentJoint] = -fr.placement.act(pin.Force(R.T @ f, np.zeros(3)))
        out[k] = structure.G.T @ (pin.rnea(model, data, q, z, z, fext) - pin.rnea(model, data, q, z, z))
    return out


def palpation_force(t: np.ndarray, *, period: float = 2.0, peak: float = 1.5, rng: np.random.Generator | int = 0) -> np.ndarray:
    """Tip force (N, 3) [N] of a palpation: one smooth press (sin² pulse, half of each ``period``)
    per period, mostly along −z (the tip pushing down) with a random lateral part, zero between presses."""
    rng = np.random.default_rng(rng)
    t = np.asarray(t, float) - t[0]
    k = np.floor(t / period).astype(int)
    phase = (t - k * period) / (0.5 * period)
    shape = np.where(phase < 1.0, np.sin(np.pi * np.clip(phase, 0.0, 1.0)) ** 2, 0.0)
    dirs = np.column_stack([rng.normal(0.0, 0.3, k.max() + 1), rng.normal(0.0, 0.3, k.max() + 1), -np.ones(k.max() + 1)])
    amp = rng.uniform(0.5, 1.0, k.max() + 1) * peak
    return (shape * amp[k])[:, None] * dirs[k]

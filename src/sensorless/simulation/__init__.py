"""Simulated data with known ground truth.

* :mod:`.synthetic`: fixed-base logs from RNEA + friction (no simulator needed);
* :mod:`.wrench_log`: floating-base logs with contact wrenches solving the dynamics;
* :mod:`.mujoco_scene`, :mod:`.quadruped`: MuJoCo quadruped scenes and scenarios
  (imported lazily: ``from sensorless.simulation.quadruped import simulate``);
* :mod:`.hopping_leg`: a leg on a passive vertical rail hopping on a force plate (MuJoCo, lazily).
"""

from .current_arm import StribeckTruth, simulate as simulate_current_log, stribeck_truth, with_payload
from .synthetic import NoiseSpec, TruthModel, add_white_noise, map_body_inertias, perturbed_truth, streamed_fourier_log, synthetic_trajectory
from .wrench_log import walking_flags, wrench_log

__all__ = ["StribeckTruth", "simulate_current_log", "stribeck_truth", "with_payload", "NoiseSpec", "TruthModel", "add_white_noise", "map_body_inertias", "perturbed_truth", "streamed_fourier_log", "synthetic_trajectory", "walking_flags", "wrench_log"]

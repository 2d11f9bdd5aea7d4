"""Simulated data with known ground truth.

* :mod:`.synthetic`: fixed-base logs from RNEA + friction (no simulator needed);
* :mod:`.mujoco_scene`, :mod:`.quadruped`: MuJoCo quadruped scenes and scenarios
  (imported lazily: ``from sensorless.simulation.quadruped import simulate``).
"""

from .synthetic import TruthModel, perturbed_truth, streamed_fourier_log, synthetic_trajectory

__all__ = ["TruthModel", "perturbed_truth", "streamed_fourier_log", "synthetic_trajectory"]

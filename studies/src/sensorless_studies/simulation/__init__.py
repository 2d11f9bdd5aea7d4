"""Simulated data with known ground truth (the fixed-base synthetic logs are :mod:`sensorless.testing`).

* :mod:`.wrench_log`: floating-base logs with contact wrenches solving the dynamics;
* :mod:`.mujoco_scene`, :mod:`.quadruped`: MuJoCo quadruped scenes and scenarios
  (imported lazily: ``from sensorless_studies.simulation.quadruped import simulate``);
* :mod:`.hopping_leg`: a leg on a passive vertical rail hopping on a force plate (MuJoCo, lazily).
"""

from .current_arm import StribeckTruth, simulate as simulate_current_log, stribeck_truth, with_payload
from .wrench_log import walking_flags, wrench_log

__all__ = ["StribeckTruth", "simulate_current_log", "stribeck_truth", "with_payload", "walking_flags", "wrench_log"]

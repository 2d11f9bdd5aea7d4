"""Learned torque models (PyTorch, CPU): residual correction, pure-learning baselines.

Needs the optional dependency ``torch`` (``pip install sensorless[learning]``).
"""

from .features import WindowFeatures, sliding_window
from .io import load_network
from .mlp import TrainConfig
from .models import HybridModel, LearnedTorqueModel, MLPTorqueModel
from .validated import ValidatedHybridModel, residual_scale

__all__ = [
    "HybridModel",
    "LearnedTorqueModel",
    "MLPTorqueModel",
    "TrainConfig",
    "ValidatedHybridModel",
    "WindowFeatures",
    "load_network",
    "residual_scale",
    "sliding_window",
]

"""Learned torque models (PyTorch, CPU): residual correction, pure-learning baselines.

Needs the optional dependency ``torch`` (``pip install sensorless[learning]``).
"""

from .features import Standardizer, WindowFeatures, sliding_window
from .io import load_network, save_network
from .mlp import (
    MLP,
    LSTMRegressor,
    PerJointMLP,
    TrainConfig,
    build_network,
    deterministic_torch,
    train_network,
)
from .models import HybridModel, LearnedTorqueModel, MLPTorqueModel
from .validated import ValidatedHybridModel, residual_scale

__all__ = [
    "MLP",
    "HybridModel",
    "LSTMRegressor",
    "LearnedTorqueModel",
    "MLPTorqueModel",
    "PerJointMLP",
    "Standardizer",
    "TrainConfig",
    "ValidatedHybridModel",
    "WindowFeatures",
    "build_network",
    "deterministic_torch",
    "load_network",
    "residual_scale",
    "save_network",
    "sliding_window",
    "train_network",
]

"""Figures and console tables."""

from .plots import plot_torques
from .tables import metrics_table

__all__ = ["metrics_table", "plot_torques"]

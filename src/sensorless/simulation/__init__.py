"""Simulated data with known ground truth."""

from .synthetic import TruthModel, perturbed_truth, streamed_fourier_log, synthetic_trajectory

__all__ = ["TruthModel", "perturbed_truth", "streamed_fourier_log", "synthetic_trajectory"]

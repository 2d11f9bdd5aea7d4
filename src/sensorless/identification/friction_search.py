"""Identification with the friction law chosen from the data: noise-aware Coulomb smoothing, a rest
gate and searched Stribeck velocities / transition widths (:mod:`~.friction` sets them up; one
:func:`~sensorless.identification.identify` pass fits the model with the candidates)."""

from __future__ import annotations

from typing import Iterable

from ..data.trajectory import Trajectory
from ..regressor.terms import ModelStructure
from .friction import friction_setup, record_search
from .identify import identify

__all__ = ["identify_friction"]


def identify_friction(
    structure: ModelStructure,
    train: Iterable[Trajectory],
    *,
    coulomb_smoothing: "str | float" = "auto",
    stribeck_velocity: "str | float | dict" = "auto",
    rest_velocity: "str | float" = 0.0,
    factor: float = 3.0,
    identify_kwargs: dict | None = None,
    noise_logs: Iterable[Trajectory] | None = None,
    lowpass_hz: float | None = None,
    width_grid: "str | dict | None" = "auto",
):
    """Identify with noise-aware Coulomb smoothing, a rest gate and searched Stribeck velocities.

    ``coulomb_smoothing``: "auto" (ε = ``factor`` σ_v, :mod:`~.friction`) or ε for every joint
    (0 = sgn). ``rest_velocity``: "auto" (δ = :data:`~.friction.REST_SIGMAS` σ_v) or δ for every joint
    (0 = no rest gate). ``stribeck_velocity``: "auto" (grid search per joint with a ``stribeck``
    term) or vs. ``noise_logs``/``lowpass_hz``: the unfiltered logs and the low-pass the training
    logs went through (:mod:`~.friction`); default: the noise of the training logs as they are.
    ``stribeck_velocity`` may also be candidate values per joint (``{joint: [vs, …]}``).
    ``width_grid``: "auto" (fitted transition widths, :func:`~.friction.transition_grid`, when ε is "auto"),
    candidate widths per joint, or None (w = ε).
    Runs :func:`~sensorless.identification.identify` once with ``identify_kwargs`` (with the
    candidates when vs or w is searched: one compression pass, :mod:`~.stribeck`). Returns
    ``(result, FrictionFit)``.
    """
    train = list(train)
    kw = dict(identify_kwargs or {})
    s, fit, auto_vs = friction_setup(structure, train, coulomb_smoothing, stribeck_velocity, rest_velocity,
                                     factor, noise_logs, lowpass_hz, width_grid)
    if not (auto_vs or fit.width_grid):
        return identify(s, train, **kw), fit
    result = identify(s, train, stribeck_grid=fit.stribeck_grid if auto_vs else None, width_grid=fit.width_grid,
                      **kw)
    return result, record_search(fit, result)

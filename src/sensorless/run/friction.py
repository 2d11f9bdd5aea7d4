"""The friction-law policy of a run: on which training logs the Coulomb smoothing ε and the Stribeck
candidates are measured (every log where each joint moves locally; the first log on the client of a
Dask run), and how the choice is recorded in result.json ``settings.friction``."""

from __future__ import annotations

import warnings
from typing import Callable

from ..errors import setting
from .logs import load_logs

__all__ = ["friction_settings", "friction_logs", "measure_friction", "client_friction", "needs_friction_law"]


def needs_friction_law(structure, coulomb_smoothing) -> bool:
    """Whether the law is measured: a per-joint structure with ε 'auto' or a Stribeck term."""
    from .model import is_plain

    return is_plain(structure) and (coulomb_smoothing == "auto" or "stribeck" in structure.joint_terms)


def friction_settings(fit, measured, first) -> dict:
    """result.json ``settings.friction``; ``measured``: the fit ε was measured by (auto smoothing), if any."""
    doc = fit.to_dict()
    if measured is not None and measured.coulomb_smoothing_mode == "auto":
        doc.update(coulomb_smoothing_mode="auto",
                   coulomb_smoothing_from=[str(p) for p in first] if isinstance(first, (list, tuple)) else str(first),
                   velocity_noise=measured.to_dict().get("velocity_noise"))
    return doc


def friction_logs(structure, train: list, data: list) -> tuple[list, list]:
    """The logs the friction law is measured on: the first training log when every joint moves in
    it (the same as on a cluster), else all of them (a joint held still has v ≡ 0, and six
    single-joint calibration logs gave ε ≈ 0 on five joints)."""
    from ..identification.friction import moving_joints

    if len(train) == 1 or moving_joints(structure, train[0]).all():
        return train[:1], data[:1]
    return train, list(data)


def measure_friction(structure, first: list, path, r, prep: dict, coulomb_smoothing, stribeck_velocity, lowpass):
    """The friction law (ε, and the Stribeck candidates) measured on the training logs ``first``
    read from ``path`` (one path, or one per log: every training log locally, the first one on a
    cluster; :func:`~sensorless.identification.friction.friction_structure`, each joint measured on
    the logs where it moves); the velocity noise is read before the low-pass colours it."""
    from ..identification.friction import friction_structure

    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    raw = load_logs(paths, r, **{**prep, "lowpass": None}) if lowpass and coulomb_smoothing == "auto" else None
    return friction_structure(structure, first, coulomb_smoothing=coulomb_smoothing,
                              stribeck_velocity=stribeck_velocity, noise_logs=raw, lowpass_hz=lowpass)


def client_friction(structure, first: list, path, r, prep: dict, coulomb_smoothing, stribeck_velocity, lowpass,
                    say: Callable[[str], None] | None = None):
    """On a Dask run: the workers fit the friction law of :func:`measure_friction` (ε, and the Stribeck
    candidates, chosen on the client from the summed equations). Without a readable first log: sgn(v)
    (ε = 0) and a fixed vs, with a warning."""
    if not first:
        warnings.warn(f"{setting('execution.scheduler')}: the first training log ({path}) is not usable on this "
                      f"machine; {setting('model.coulomb_smoothing', 'auto')} falls back to sgn(v) (ε = 0)",
                      stacklevel=2)
        return structure, None
    s, fit = measure_friction(structure, first, path, r, prep, coulomb_smoothing, stribeck_velocity, lowpass)
    eps = ", ".join(f"{j} {e:.3g}" for j, e in fit.coulomb_smoothing.items())
    if say is not None:
        say(f"{setting('execution.scheduler')}: Coulomb smoothing from {path} (ε [rad/s]: {eps})"
            + ("; Stribeck candidates from the same log" if fit.stribeck_grid else ""))
    return s, fit

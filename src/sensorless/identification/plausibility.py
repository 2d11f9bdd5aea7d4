"""Plausibility of an identified model: errors that name the quantity, checked before anything is written.

:func:`plausibility_problems` lists, one line each:

* a non-finite parameter;
* a body heavier than the whole prior robot (Σ of the prior's masses);
* a CoM farther from its body than the body's size: ``|c − centre| > 3 a_max`` for the body's
  bounding ellipsoid (centre, largest semi-axis ``a_max``; :func:`~.ellipsoids.resolve_ellipsoids`,
  automatic from the geometry and the prior), i.e. more than one body diameter outside it;
* the identified total mass more than :data:`TOTAL_MASS_TOLERANCE` off the prior's when the
  data determine it (total-mass verdict ``data``, :mod:`.verdicts`; a floating base).

:func:`check_plausibility` raises :class:`~sensorless.errors.PlausibilityError` with them
(``sensorless identify`` exits 2 and writes no output folder) unless ``accept`` is set.

The mass and CoM rules judge what is *presented* as a body: the inertials ``model.urdf`` will
hold (:func:`~.urdf_values.urdf_inertials` for ``urdf_values``: the prior's mass where the data do
not determine it, the identified dynamics unchanged; ``"regularised"``: the fitted values).
A mass the data do not determine is labelled ``prior`` in ``result.json`` and never presented.
"""

from __future__ import annotations

import numpy as np

from ..errors import PlausibilityError, setting

__all__ = ["COM_SIZE_FACTOR", "TOTAL_MASS_TOLERANCE", "check_plausibility", "plausibility_problems"]

TOTAL_MASS_TOLERANCE = 0.5  # relative
COM_SIZE_FACTOR = 3.0  # |c − centre| > this × the ellipsoid's largest semi-axis


def plausibility_problems(result, prior: np.ndarray | None = None, ellipsoids=None, *,
                          urdf_values: str = "prior") -> list[str]:
    """One line per implausible quantity of ``result`` (module docstring)."""
    from .urdf_values import urdf_inertials

    from .ellipsoids import resolve_ellipsoids

    s = result.structure
    names = list(result.robot.body_names)
    p = np.asarray(result.parameters, dtype=float)
    prior = s.prior() if prior is None else np.asarray(prior, dtype=float)
    out = [f"parameter '{lab}' is {v}" for lab, v in zip(s.labels, p) if not np.isfinite(v)]
    if out:
        return out
    P = urdf_inertials(result, urdf_values)[0].reshape(-1, 10)
    total0 = float(prior[0: s.n_body_params: 10].sum())
    if total0 > 0:
        out += [f"body '{b}' mass {m:.4g} kg is more than the whole prior robot ({total0:.4g} kg)"
                for b, m in zip(names, P[:, 0]) if m > total0]
    try:
        ell = resolve_ellipsoids(result.robot, ellipsoids, prior=prior)
    except Exception:  # noqa: BLE001 - no geometry: the CoM check is skipped, not the others
        ell = {}
    for k, b in enumerate(names):
        E = ell.get(b)
        if E is None or not P[k, 0] > 0:
            continue
        c = P[k, 1:4] / P[k, 0]
        dist = float(np.linalg.norm(c - E.center))
        size = float(np.max(E.semi_axes))
        if dist > COM_SIZE_FACTOR * size:
            out.append(f"body '{b}' CoM ({', '.join(f'{x:.3g}' for x in c)}) m is {dist:.3g} m from the body's "
                       f"centre, more than its size ({2 * size:.3g} m) outside it")
    tot = (result.diagnostics.get("verdicts") or {}).get("robot", {}).get("total_mass")
    if tot and tot.get("verdict") == "data" and total0 > 0:
        m = float(p[: s.n_body_params: 10].sum())
        if abs(m - total0) > TOTAL_MASS_TOLERANCE * total0:
            out.append(f"total mass {m:.4g} kg is off by {100 * (m / total0 - 1):+.0f} % from the prior's "
                       f"{total0:.4g} kg (more than {100 * TOTAL_MASS_TOLERANCE:.0f} %)")
    return out


def check_plausibility(result, prior: np.ndarray | None = None, ellipsoids=None, *, accept: bool = False,
                       urdf_values: str = "prior") -> list[str]:
    """:class:`PlausibilityError` naming the first problems unless ``accept``; returns the problems."""
    problems = plausibility_problems(result, prior, ellipsoids, urdf_values=urdf_values)
    if problems and not accept:
        more = f" (+{len(problems) - 3} more)" if len(problems) > 3 else ""
        raise PlausibilityError("implausible model: " + "; ".join(problems[:3]) + more
                                + f"; check the log's units and excitation, or keep it with {setting('accept', True)}")
    return problems

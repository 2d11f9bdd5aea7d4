"""Which inertial values go into ``model.urdf``: the prior's masses where the data do not determine them.

A body whose mass verdict (:mod:`.verdicts`) is not ``data`` gets the prior's mass in the URDF.
Individual masses of a fixed-base arm lie in the base-parameter null space (they regroup into
the first moments and inertias of the bodies above), so the remaining parameters are moved
along that null space, ``π_u = π̂ + Δ`` with ``B Δ = 0`` (``B``: standard → base parameters) and
``‖S⁻¹Δ‖`` minimal (``S``: per-body mass/length scales): the URDF then predicts exactly the
identified dynamics on every motion. A second step then moves every other direction the data do
not see to the prior as well, ``min ‖S⁻¹(π_u − π_prior)‖`` with the same constraints (the CoMs and
inertias of links seen only through a floating base's rows). When the prior's masses cannot be
reached, or a body would stop being physical, the regularised values are written and the reason
recorded.
``mode="regularised"`` (``--urdf-values regularised``) always writes the regularised values.
A result that carries a presented model (``diagnostics["presented"]``, :mod:`.presented`: physically
consistent, nearest the prior within the data's uncertainty, the prior's masses where the data do not
determine them) is written as it is: model.urdf then holds exactly the values result.json shows.
"""

from __future__ import annotations

import numpy as np

__all__ = ["URDF_VALUES", "greedy_prefixes", "reach_prior_masses", "urdf_inertials", "urdf_comment"]

URDF_VALUES = ("prior", "regularised")


def _prior_bodies(verdicts: dict, names) -> np.ndarray:
    """The prior's (n, 10) body parameters, rebuilt from the verdict entries."""
    out = np.zeros((len(names), 10))
    keys = ("ixx", "ixy", "iyy", "ixz", "iyz", "izz")
    for k, b in enumerate(names):
        e = verdicts["bodies"][b]
        m0 = e["mass"]["prior"] or 0.0
        out[k, 0] = m0
        out[k, 1:4] = [m0 * (e[f"com_{a}"]["prior"] or 0.0) for a in "xyz"]
        out[k, 4:10] = [e[q]["prior"] or 0.0 for q in keys]
    return out


def urdf_inertials(result, mode: str = "prior") -> tuple[np.ndarray, dict]:
    """``(π for the URDF, info)``; ``info["prior_mass_bodies"]`` lists the bodies written with the
    prior's mass, ``info["fallback"]`` why the regularised values were written instead. Memoised on
    ``result`` per mode (the plausibility check and the writer ask for the same values)."""
    memo = result.__dict__.setdefault("_urdf_inertials", {})
    if mode not in memo:
        memo[mode] = _urdf_inertials(result, mode)
    pi, info = memo[mode]
    return pi.copy(), dict(info)


def _urdf_inertials(result, mode: str) -> tuple[np.ndarray, dict]:
    pi = np.array(result.inertial_parameters, dtype=float)
    verdicts = result.diagnostics.get("verdicts")
    names = list(result.robot.body_names)
    info: dict = {"values": mode, "prior_mass_bodies": []}
    if mode == "regularised" or not verdicts:
        return pi, info
    shown = result.diagnostics.get("presented")
    if shown is not None:  # the presented model (:mod:`.presented`), already nearest the prior, or the fit: written as is
        info["prior_mass_bodies"] = list(shown.get("prior_mass_bodies", []))
        info["values"] = "presented"
        return pi, info
    P0 = _prior_bodies(verdicts, names)
    if not (P0[:, 0] > 0).any():  # no inertial prior (e.g. a robot authored without masses): nothing to move toward
        return pi, info
    fix = [k for k, b in enumerate(names) if verdicts["bodies"][b]["mass"]["verdict"] != "data" and P0[k, 0] > 0]
    blind = any(q.get("verdict") != "data" for v in verdicts["bodies"].values() for q in v.values()
                if isinstance(q, dict))
    if not fix and not blind:
        return pi, info
    nb = len(pi)
    m = np.where(P0[:, 0] > 0, P0[:, 0], max(P0[:, 0].mean(), 1e-3))
    ell = 0.1
    S = np.repeat(m, 10) * np.tile([1, ell, ell, ell] + [ell**2] * 6, len(m))
    # greedily, farthest from the prior first: keep each body whose prior mass stays reachable
    order = sorted(fix, key=lambda k: -abs(np.log(max(pi[10 * k], 1e-12) / P0[k, 0])))
    def reach(ks: list[int]) -> np.ndarray | None:
        return reach_prior_masses(pi, result.base.B[:, :nb], S, np.array(ks, dtype=int), P0[ks, 0])

    if _physical(pi) or reach([]) is not None:
        kept, cand = greedy_prefixes(order, reach)
        # then every other direction the data do not see goes to the prior too (CoMs and inertias of
        # bodies the log cannot resolve, e.g. links seen only through the floating-base rows)
        polished = reach_prior_masses(pi, result.base.B[:, :nb], S, np.array(kept, dtype=int), P0[kept, 0],
                                       target=P0.ravel())
    else:  # no physical bodies give the identified dynamics (an unconstrained fit): fixing masses, or
        # moving toward the prior, only adds to or keeps those constraints, so no program is feasible
        kept, cand, polished = [], None, None
    cand = pi if cand is None else cand
    if polished is not None:
        cand = polished
    info["prior_mass_bodies"] = [names[k] for k in fix if k in kept]
    rest = [names[k] for k in fix if k not in kept]
    if rest:
        info["undetermined_mass_bodies"] = rest
        info["fallback"] = (f"regularised masses for {', '.join(rest)}: with the prior's, no physical bodies "
                            "reproduce the identified dynamics")
    if not kept and polished is None:
        info["values"] = "regularised"
    elif polished is not None:
        info["unseen_to_prior"] = True
    return cand, info


def greedy_prefixes(order: list[int], reach) -> tuple[list[int], np.ndarray | None]:
    """The greedy ``for k in order: keep k if reach(kept + [k]) is not None`` — ``(kept, reach(kept))``
    — in O(log n) calls per body it rejects: fixing a subset of the masses relaxes fixing them all,
    so ``reach(kept + rest[:j])`` succeeds for every j up to the first body the greedy rejects, found by
    galloping down from the whole list, then bisection; each call is on a list the greedy builds (the
    same program, the same numbers), the result on exactly its final list."""
    kept: list[int] = []
    cand = None
    rest = list(order)
    while rest:
        every = reach(kept + rest)
        if every is not None:
            return kept + rest, every
        lo, hi, best = 0, len(rest), None  # kept + rest[:lo] reachable, kept + rest[:hi] not
        step = 1  # gallop down from the top first: the bodies nearest the prior, last in order, are the usual misfits
        while hi - step > lo:
            trial = reach(kept + rest[:hi - step])
            if trial is not None:
                lo, best = hi - step, trial
                break
            hi, step = hi - step, 2 * step
        while hi - lo > 1:
            mid = (lo + hi) // 2
            trial = reach(kept + rest[:mid])
            if trial is not None:
                lo, best = mid, trial
            else:
                hi = mid
        if lo:
            kept, cand = kept + rest[:lo], best
        rest = rest[lo + 1:]  # rest[lo]: the body the greedy rejects
    return kept, cand


def _physical(pi) -> bool:
    from ..parameters import check_physical_consistency

    return all(r.consistent for r in check_physical_consistency(pi))


def reach_prior_masses(pi, B, S, fix, m0, target=None) -> np.ndarray | None:
    """``π̂ + Δ`` with ``B Δ = 0``, the masses ``fix`` at ``m0``, every body's pseudo-inertia ⪰ 0 and
    ``‖S⁻¹Δ‖`` minimal, or with ``target`` ``‖S⁻¹(π̂ + Δ − target)‖`` minimal (a small SDP,
    :mod:`.prior_projection`); None when infeasible, unsolved or not physical."""
    from .prior_projection import solve_prior_projection

    y = solve_prior_projection(pi, B, S, fix, m0, target=target)
    if y is None:
        return None
    out = pi + S * y
    out[fix * 10] = m0
    return out if _physical(out) else None


def urdf_comment(info: dict) -> str | None:
    """The XML comment for model.urdf (None when every mass is the regularised, data-determined one)."""
    out = []
    if info.get("prior_mass_bodies"):
        out.append(f"sensorless: the data do not determine the mass of {', '.join(info['prior_mass_bodies'])}: "
                   "the prior's mass is written (the other inertial parameters moved along directions no "
                   "joint-torque log sees, so the identified dynamics are unchanged); --urdf-values regularised "
                   "writes the regularised values")
    if info.get("undetermined_mass_bodies"):
        out.append(f"sensorless: the data do not determine the mass of {', '.join(info['undetermined_mass_bodies'])} "
                   f"either; {info.get('fallback', '')}")
    return " | ".join(out) or None

"""The ``presliding`` joint term of a rigid-body model: which joints keep it, with which k.

The term's column is the Coulomb state s_c of :mod:`sensorless.regressor.friction_state` (one
presliding distance 1/k, the play h against position noise), integrated along each log from 0, so

    τ_j = [Y π]_j + fv v + fc tanh(v/ε) + (fs − fc) e^{−(v/vs)²} tanh(v/ε) + o + Ia v̇ + f_p s_c(q history).

k enters non-linearly. It is chosen per joint by the rule of the friction-only fit
(:func:`~.friction_fit.fit_joint_friction`, the same k grid, variable projection and BIC), on
the torque the rigid body leaves to friction: (1) the model is identified without the term
(``identify`` as asked, the Stribeck search included); (2) on each training log the friction
residual r_j = τ_j − [Y π]_j − Ia_j v̇_j (:func:`~.friction.friction_residual`) is fitted per
joint with the static law and with the state; (3) a joint keeps ``presliding`` (with that k and
h) only if the state law's BIC is below the static law's, and the model is identified again with
the kept terms. A joint without presliding or hysteresis keeps its static law, and when no joint
keeps the term the first fit is the result. The choice is in ``diagnostics["presliding_search"]``.
"""

from __future__ import annotations

import dataclasses


from ..errors import OptionError, setting
from ..regressor.terms import ModelStructure
from .friction import friction_residual
from .friction_fit import JointSeries, fit_joint_friction
from .stribeck import carry_prior

__all__ = ["needs_presliding_search", "search_presliding"]


def needs_presliding_search(structure) -> bool:
    """True when a joint has the ``presliding`` term but no presliding distance yet."""
    if "presliding" not in getattr(structure, "joint_terms", ()):
        return False
    given = getattr(structure, "presliding", None) or {}
    return any("presliding" in structure.terms_of(j) and j not in given for j in structure.robot.term_joints)


def _without(structure: ModelStructure, joints) -> ModelStructure:
    """``structure`` with the ``presliding`` term removed from ``joints``."""
    per = {j: tuple(t for t in structure.terms_of(j) if not (t == "presliding" and j in joints))
           for j in structure.robot.term_joints}
    return dataclasses.replace(structure, joint_terms=structure.joint_terms, per_joint_terms=per)


def search_presliding(identify, structure: ModelStructure, data, kwargs: dict):
    """Identify ``structure`` on the logs ``data`` choosing each joint's presliding term (module
    docstring); ``identify(model, data, **kwargs)`` is the identification to run."""
    if type(structure) is not ModelStructure:
        raise OptionError(f"the 'presliding' joint term needs a per-joint model without contacts or coupled "
                          f"joints (got {type(structure).__name__}); remove presliding from {setting('joint_terms')}")
    logs = list(data)
    given = structure.presliding or {}
    asked = [j for j in structure.robot.term_joints if "presliding" in structure.terms_of(j) and j not in given]
    kw = dict(kwargs)
    prior = kw.pop("prior", None)
    first = _without(structure, asked)
    result0 = identify(first, logs, prior=carry_prior(prior, structure, first), **kw)
    s0 = result0.structure
    residuals = [friction_residual(s0, result0.parameters, t) for t in logs]
    joints = list(s0.robot.term_joints)
    record, kept = {}, {}
    for j in asked:
        c = joints.index(j)
        series = []
        for t, (v, r) in zip(logs, residuals):
            q = t.q[:, list(t.joint_names).index(j)]
            series.append(JointSeries(t.t, q, v[:, c], r[:, c], source=t.source))
        terms = ("fc",) + tuple(x for x in ("stribeck", "fv", "offset") if x in s0.terms_of(j))
        fit = fit_joint_friction(series, joint=j, terms=terms, state="auto", coulomb_smoothing=s0.smoothing_of(j))
        keep = fit.law.kind == "state"
        record[j] = {"kept": keep, "reason": fit.reason, "bic_static": fit.bic["static"], "bic_state": fit.bic["state"],
                     "presliding_distance": 1.0 / fit.law.k if keep else None, "play": fit.law.play if keep else None}
        if keep:
            kept[j] = {"k": float(fit.law.k), "play": float(fit.law.play)}
    if not kept and not given:
        result0.diagnostics["presliding_search"] = record
        return result0
    per = {j: s0.terms_of(j) + (("presliding",) if j in kept or j in given else ()) for j in joints}
    final = dataclasses.replace(s0, joint_terms=s0.joint_terms + ("presliding",), per_joint_terms=per,
                                presliding={**given, **kept})
    kw["stribeck_grid"] = None  # vs chosen in the first fit
    result = identify(final, logs, prior=carry_prior(prior, structure, final), **kw)
    result.diagnostics["presliding_search"] = record
    return result

"""Verdicts on physical quantities: is each one determined by the data, taken from the prior, or neither?

Every physical quantity the tool reports is linear (or linearised) in the standard parameters,
``φ = aᵀπ``: each body's mass, CoM ``c = h/m`` (linearised at the estimate,
``a = (e_h − c e_m)/m``), the six inertia entries about the body frame origin, the total mass,
and each joint term (fv, fc, stribeck, offset, armature). From the compressed, weighted normal
equations ``A = Σ_r w_r A_r``, ``b = Σ_r w_r b_r`` of the fit (:class:`NormalEquations`) and the
weighted residual variance ``s² = Σ_r w_r RSS_r / (N·rows − rank)``:

* **data-alone std** ``σ_φ² = s² aᵀA⁺a``. ``A`` is Jacobi-equilibrated and eigendecomposed; the
  eigenvalues below :data:`NULL_CUTOFF` × the largest span its numerical null space. When more
  than :data:`NULL_FRACTION` of ``a`` (after equilibration) lies in it, no amount of this data
  determines ``φ``: ``std = inf`` (``None`` in JSON).
* **prior share** (LMI only). The regulariser's Hessian at the prior, ``H = (γ c / N) S⁻¹ M S⁻¹``
  (``S`` the solver's scaling, ``M`` the constant-pullback metric of each body, the identity for
  "euclidean", ``joint_weight · I`` on joint terms; the entropic regulariser's second-order
  expansion is the pullback metric) splits the regularised estimate linearly,
  ``φ̂ ≈ aᵀ(A+H)⁺b + aᵀ(A+H)⁺Hπ0 = φ_data + φ_prior`` — exact for a quadratic regulariser
  without active constraints, a linearisation otherwise — and
  ``prior_share = |φ_prior| / (|φ_data| + |φ_prior|)``.
* **resampled std** (:mod:`.resampling`, when the fit kept its time blocks): the blocked-jackknife
  spread of the same data-alone estimate over time blocks and logs, ``std_resampled``, and its 95 %
  ``interval``; it sees what the linear std cannot (errors in q, v, v̇, quantization, unmodelled
  torque, correlated residuals). The verdict uses ``std = max(std_data, std_resampled)``;
  ``linear_too_narrow`` marks entries where the two differ by more than 2×.
* **verdict**: ``"data"`` when ``std ≤`` :data:`DATA_REL_STD` ``× max(|φ̂|, |φ0|, unit)``, and, for
  a mass (a body's, the total), when its 95 % interval is narrower than the value itself,
  (``unit``: the body's mass, ``ℓ``, ``m ℓ²`` scale of the solver, ``ℓ`` its radius of gyration;
  for a joint term :data:`JOINT_UNIT` × the value that alone explains the joint's RMS torque) and
  the prior share is below ½; else ``"prior"`` when a prior fixed the value (LMI with γ > 0, or
  least squares with standard parameters closest to the prior) and the body's prior is not
  massless; else ``"undetermined"``.
"""

from __future__ import annotations

import numpy as np

from ..regressor.normal_equations import NormalEquations
from ..regressor.terms import ModelStructure

__all__ = ["DATA_REL_STD", "NULL_CUTOFF", "NULL_FRACTION", "JOINT_UNIT", "VERDICTS", "compute_verdicts",
           "linear_split", "regulariser_hessian", "body_verdict", "quantity_verdict", "present_verdicts"]

VERDICTS = ("data", "prior", "undetermined")
DATA_REL_STD = 0.2  # data-alone std ≤ 20 % of the quantity's scale → determined by the data
NULL_CUTOFF = 1e-10  # relative eigenvalue of the equilibrated A below which a direction is unseen
NULL_FRACTION = 1e-6  # share of a quantity's (equilibrated) direction in that null space → std = inf
JOINT_UNIT = 0.1  # a joint term's unit: this × the value that alone explains the row's RMS torque
INERTIA = ("ixx", "ixy", "iyy", "ixz", "iyz", "izz")


def linear_split(A: np.ndarray, b: np.ndarray, H: np.ndarray, pi0: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(aᵀ(A+H)⁺b, aᵀ(A+H)⁺Hπ0)`` for the rows of ``a`` (k, p): the data and prior parts of the
    minimiser of ``πᵀAπ − 2bᵀπ + (π−π0)ᵀH(π−π0)`` (equilibrated pseudo-inverse)."""
    K = A + H
    dk = np.sqrt(np.maximum(np.diag(K), 1e-300 * max(float(np.diag(K).max()), 1e-300)))
    Kh = K / np.outer(dk, dk)
    Kp = np.linalg.pinv(0.5 * (Kh + Kh.T), rcond=1e-13, hermitian=True)
    Z = (np.atleast_2d(a) / dk) @ Kp / dk  # aᵀ(A+H)⁺ per row
    return Z @ b, Z @ (H @ pi0)


def regulariser_hessian(structure: ModelStructure, prior: np.ndarray, lmi: dict, gamma: float, regularization,
                        A: np.ndarray, c: float, n_samples: int) -> np.ndarray:
    """``H`` (p×p) of ``γ/N · R`` in π coordinates, times ``c`` (the solver's objective is relative)."""
    from ..parameters import pseudo_inertia
    from .regularizers import REGULARIZERS, eigenvalue_floor, pullback_matrix

    p, nb = structure.n_params, structure.n_body_params
    if not gamma or regularization is None:
        return np.zeros((p, p))
    reg = REGULARIZERS[regularization]() if isinstance(regularization, str) else regularization
    settings = lmi.get("settings", {})
    m = np.asarray(settings["body_mass_scale"], dtype=float)
    ell = np.asarray(settings["body_length_scale"], dtype=float)
    per_body = np.stack([m, m * ell, m * ell, m * ell] + [m * ell**2] * 6, axis=1).ravel()
    dA = np.diag(A)[nb:]
    ok = dA > 1e-14 * c
    js = np.where(ok, np.sqrt(c / np.where(ok, dA, 1.0)), 1.0)
    scale = np.concatenate([per_body, js])
    x0 = prior / scale
    Mx = np.zeros((p, p))
    for k in range(nb // 10):
        sl = slice(10 * k, 10 * k + 10)
        if getattr(reg, "name", "") == "euclidean":
            Mx[sl, sl] = np.eye(10)
        else:
            Mx[sl, sl] = pullback_matrix(eigenvalue_floor(pseudo_inertia(x0[sl]), getattr(reg, "delta", 1e-3)))
    jw = float(getattr(reg, "joint_weight", 1.0))
    Mx[nb:, nb:] = jw * np.eye(p - nb)
    return (gamma * c / max(n_samples, 1)) * (Mx / np.outer(scale, scale))


def _quantities(structure: ModelStructure, params: np.ndarray, prior: np.ndarray, scale: np.ndarray,
                row_unit: dict[str, float]):
    """(group, name, quantity, a, value, prior value, unit) for every reported quantity."""
    p, nb = structure.n_params, structure.n_body_params
    out = []
    for k, body in enumerate(structure.robot.body_names):
        i = 10 * k
        m, m0 = params[i], prior[i]
        mr = m if m > 0 else (m0 if m0 > 0 else scale[i])
        e = np.eye(p)
        out.append(("bodies", body, "mass", e[i], m, m0, scale[i]))
        ell = scale[i + 1] / scale[i]
        for ax, name in enumerate("xyz"):
            a = (e[i + 1 + ax] - (params[i + 1 + ax] / mr) * e[i]) / mr
            c0 = prior[i + 1 + ax] / m0 if m0 > 0 else 0.0
            out.append(("bodies", body, f"com_{name}", a, params[i + 1 + ax] / mr, c0, ell))
        for j, name in enumerate(INERTIA):
            out.append(("bodies", body, name, e[i + 4 + j], params[i + 4 + j], prior[i + 4 + j], scale[i + 4 + j]))
    tot = np.zeros(p)
    tot[0:nb:10] = 1.0
    out.append(("robot", "robot", "total_mass", tot, params[0:nb:10].sum(), prior[0:nb:10].sum(),
                float(scale[0:nb:10].sum())))
    s = structure
    for j in s.robot.term_joints:
        for t in s.terms_of(j):
            idx = s.joint_term_index(j, t)
            a = np.zeros(p)
            a[idx] = 1.0
            out.append(("joints", j, t, a, params[idx], prior[idx], JOINT_UNIT * row_unit.get(f"{j}.{t}", 1.0)))
    return out


def quantity_verdict(std: float, share: float | None, value: float, prior: float, unit: float,
                     prior_fixed: bool, half_width: float | None = None) -> str:
    """``data`` | ``prior`` | ``undetermined`` (module docstring); ``half_width``: the 95 % interval's
    half-width of a mass, which must be narrower than the value (``2·half_width < |value|``)."""
    size = max(abs(value), abs(prior), abs(unit))
    narrow = half_width is None or (np.isfinite(half_width) and 2.0 * half_width < abs(value))
    if np.isfinite(std) and std <= DATA_REL_STD * size and (share is None or share < 0.5) and narrow:
        return "data"
    return "prior" if prior_fixed else "undetermined"


def body_verdict(entries: dict) -> str:
    """A body's overall verdict: its mass verdict (the mass is what a table shows first)."""
    return entries["mass"]["verdict"]


def _row_units(structure: ModelStructure, ne: NormalEquations) -> dict[str, float]:
    """``joint.term`` → ``√(c_r / A_r,jj)``: the term's value that alone explains row r's RMS torque."""
    out = {}
    rows = list(structure.row_names)
    for j in structure.robot.term_joints:
        for t in structure.terms_of(j):
            idx = structure.joint_term_index(j, t)
            col = ne.A[:, idx, idx]
            r = rows.index(j) if j in rows and rows.index(j) < len(col) else int(np.argmax(col))
            ok = col.size and col[r] > 0 and ne.c[r] > 0
            out[f"{j}.{t}"] = float(np.sqrt(ne.c[r] / col[r])) if ok else 1.0
    return out


def compute_verdicts(structure: ModelStructure, ne: NormalEquations, params: np.ndarray, *, row_weights=None,
                     method: str = "lmi", prior: np.ndarray | None = None, gamma: float = 0.0,
                     regularization=None, lmi: dict | None = None, standard: str = "closest_to_prior",
                     rank: int | None = None, resampling=None) -> dict:
    """The ``diagnostics["verdicts"]`` document: per body and joint term ``{value, prior, std_data,
    std_resampled, std, interval, linear_too_narrow, prior_share, verdict}`` (module docstring), plus the
    thresholds used. ``resampling``: the fit's time blocks (:class:`~.resampling.Resampling`), or None."""
    params = np.asarray(params, dtype=float)
    prior = structure.prior() if prior is None else np.asarray(prior, dtype=float)
    A, b, c = ne.total(None if row_weights is None else np.asarray(row_weights, dtype=float))
    w = np.ones(ne.A.shape[0]) if row_weights is None else np.asarray(row_weights, dtype=float)
    from .resampling import pinv_parts

    d, lam, V, N0 = pinv_parts(A, NULL_CUTOFF)
    n_eq = max(ne.n_samples, 1) * max(ne.A.shape[0], 1)
    s2 = float(w @ ne.residual_ss(params)) / max(n_eq - (len(lam) if rank is None else rank), 1)
    nb = structure.n_body_params
    lm = lmi or {}
    if "settings" in lm:
        m = np.asarray(lm["settings"]["body_mass_scale"], dtype=float)
        ell = np.asarray(lm["settings"]["body_length_scale"], dtype=float)
    else:
        P0 = prior[:nb].reshape(-1, 10)
        pos = P0[:, 0][P0[:, 0] > 0]
        m = np.where(P0[:, 0] > 0, P0[:, 0], 0.05 * pos.mean() if pos.size else 1.0)
        ell = np.full(len(m), 0.1)
    scale = np.concatenate([np.stack([m, m * ell, m * ell, m * ell] + [m * ell**2] * 6, axis=1).ravel(),
                            np.ones(structure.n_params - nb)])
    regularised = method == "lmi" and bool(gamma) and regularization is not None
    H = (regulariser_hessian(structure, prior, lm, float(gamma), regularization, A, c, ne.n_samples)
         if regularised else None)
    prior_set = regularised or (method in ("ols", "wls") and standard == "closest_to_prior")
    Q = _quantities(structure, params, prior, scale, _row_units(structure, ne))
    Amat = np.stack([q[3] for q in Q])
    Ah = Amat / d  # equilibrated directions
    proj = Ah @ V
    with np.errstate(divide="ignore", invalid="ignore"):
        var = s2 * np.sum(proj**2 / lam, axis=1)
    null = np.linalg.norm(Ah @ N0, axis=1) if N0.size else np.zeros(len(Q))
    undet = null > NULL_FRACTION * np.linalg.norm(Ah, axis=1)
    std = np.where(undet, np.inf, np.sqrt(np.maximum(var, 0.0)))
    std_rs = half_rs = np.full(len(Q), np.nan)
    if resampling is not None:
        resampling.row_weights = w
        std_rs, half_rs = resampling.spread(Amat)
        std_rs = np.where(undet, np.inf, std_rs)
    both = np.fmax(std, std_rs)  # nan (no resampling) → the linear std
    half = np.fmax(1.959963984540054 * std, half_rs)
    share = [None] * len(Q)
    if H is not None:
        pd, pp = linear_split(A, b, H, prior, Amat)
        share = [float(abs(y) / max(abs(x) + abs(y), 1e-300)) for x, y in zip(pd, pp)]
    massless = {body for body, mass in zip(structure.robot.body_names, prior[0:nb:10]) if not mass > 0}
    doc: dict = {"bodies": {}, "joints": {}, "robot": {}}
    for (group, name, qty, _, val, p0, unit), sd, sr, st, hw, sh in zip(Q, std, std_rs, both, half, share):
        fixed = prior_set and name not in massless and not (group == "robot" and massless)
        massy = qty in ("mass", "total_mass")
        entry = {"value": _f(val), "prior": _f(p0), "std_data": _f(sd), "std_resampled": _f(sr), "std": _f(st),
                 "interval": [_f(val - hw), _f(val + hw)] if np.isfinite(hw) else None,
                 "linear_too_narrow": None if np.isnan(sr) else bool(np.isfinite(sd) and not sr <= 2.0 * sd),
                 "prior_share": sh,
                 "verdict": quantity_verdict(float(st), sh, float(val), float(p0), float(unit), fixed,
                                             float(hw) if massy else None)}
        (doc[group] if group == "robot" else doc[group].setdefault(name, {}))[qty] = entry
    doc["settings"] = {"data_rel_std": DATA_REL_STD, "null_cutoff": NULL_CUTOFF, "null_fraction": NULL_FRACTION,
                       "joint_unit": JOINT_UNIT, "residual_variance": s2,
                       "resampling": resampling.settings() if resampling is not None else None,
                       "prior_fixes_unseen": bool(prior_set), "com": "linearised c = h/m at the estimate",
                       "inertia": "entries about the body frame origin (Pinocchio's I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)"}
    doc["counts"] = count_verdicts(doc)
    return doc


def count_verdicts(doc: dict) -> dict[str, int]:
    """How many body masses carry each verdict."""
    out = {v: 0 for v in VERDICTS}
    for entries in doc.get("bodies", {}).values():
        out[entries["mass"]["verdict"]] += 1
    return out


def _f(x) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def present_verdicts(doc: dict, structure: ModelStructure, params: np.ndarray, prior: np.ndarray,
                     rel_tol: float = 1e-4) -> dict:
    """``doc`` (:func:`compute_verdicts`) with every value taken at the presented ``params``
    (:mod:`.presented`): intervals re-centred on them, and an entry labelled ``prior`` whose value is
    not the prior's (beyond ``rel_tol``) relabelled ``undetermined``: ``prior`` means the value written is
    the prior's."""
    params = np.asarray(params, dtype=float)
    nb = structure.n_body_params
    scale = np.ones(structure.n_params)
    for group, name, qty, _, val, p0, _ in _quantities(structure, params, np.asarray(prior, dtype=float),
                                                        np.concatenate([np.ones(nb), scale[nb:]]), {}):
        e = (doc[group] if group == "robot" else doc[group].get(name, {})).get(qty)
        if e is None:
            continue
        old = e["value"]
        e["value"] = _f(val)
        if e.get("interval") and old is not None and e["value"] is not None:
            e["interval"] = [e["interval"][0] - old + e["value"], e["interval"][1] - old + e["value"]]
        if e["verdict"] == "prior" and not abs(val - p0) <= rel_tol * max(abs(p0), 1e-6):
            e["verdict"] = "undetermined"
    doc["counts"] = count_verdicts(doc)
    return doc

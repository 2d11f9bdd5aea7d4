"""Class ``numerics`` (issue 23 item 8): torque channels that are constant, zero, dead while the
joint moves, scaled by 10⁻⁶…10⁻² or 10³…10⁶, permuted or sign-flipped, fed to ``identify`` (OLS, WLS or
LMI) on the worker's simulated two-link log.

``typed``: a SensorlessError (the wanted answer). ``garbage``: the fit succeeded without a
warning and its model is wrong where it matters: non-finite parameters, or a held-out NRMSE on
the clean log above twice (and 5 points above) that of the model fitted on the clean log. ``ok``:
it succeeded and its model is as good as the clean one (a corruption the fit does not feel).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .common import one_line, setup_model

KINDS = ("constant", "zero", "dead", "scaled", "permuted", "sign")


def _nrmse(model_pred: np.ndarray, tau: np.ndarray) -> float:
    return float(np.mean(np.sqrt(np.mean((model_pred - tau) ** 2, axis=0)) / np.ptp(tau, axis=0)))


def setup(d: Path, scale: float) -> dict:
    from sensorless.identification import identify

    ctx = setup_model(d)
    tr = ctx["traj"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = identify(ctx["robot"], tr, method="ols", joint_terms=("fv", "fc"))
    ctx["clean_nrmse"] = _nrmse(clean.structure.torques(clean.parameters, tr), tr.tau)
    return ctx


def corrupt(rng, tau: np.ndarray, t: np.ndarray) -> tuple[str, np.ndarray]:
    kind = str(rng.choice(KINDS))
    tau = tau.copy()
    n, nj = tau.shape
    j = int(rng.integers(nj))
    if kind == "constant":
        tau[:, j] = float(rng.choice([1.0, -3.5, 1e-3, 250.0]))
    elif kind == "zero":
        tau[:, j] = 0.0
    elif kind == "dead":  # the channel holds its last value for 1.2–2 s while the joint moves
        span = int(rng.uniform(1.2, 2.0) / np.median(np.diff(t)))
        a = int(rng.integers(0, max(n - span, 1)))
        tau[a:a + span, j] = tau[a, j]
    elif kind == "scaled":
        factor = float(10.0 ** rng.choice([-6, -4, -3, -2, 3, 4, 6]))  # 100× up is the threshold itself
        if rng.random() < 0.5:
            tau *= factor
        else:
            tau[:, j] *= factor
    elif kind == "permuted":
        tau = tau[:, ::-1].copy() if nj == 2 or rng.random() < 0.5 else tau[:, rng.permutation(nj)]
    else:  # sign
        if rng.random() < 0.5:
            tau = -tau
        else:
            tau[:, j] = -tau[:, j]
    return kind, tau


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.errors import SensorlessError
    from sensorless.identification import identify

    tr = ctx["traj"]
    kind, tau = corrupt(rng, tr.tau, tr.t)
    if kind == "permuted" and np.array_equal(tau, tr.tau):
        return "ok", ""  # the identity permutation
    method = str(rng.choice(["ols", "wls", "lmi"], p=[0.45, 0.25, 0.3]))
    kw = {"gamma": 1e-3} if method == "lmi" else {}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = identify(ctx["robot"], tr.with_(tau=tau), method=method, joint_terms=("fv", "fc"), **kw)
    except SensorlessError:
        return "typed", ""
    except Exception as exc:  # noqa: BLE001
        return "generic", f"numerics/{kind} {method}: {type(exc).__name__}: {one_line(exc)}"
    if not np.all(np.isfinite(res.parameters)):
        return "garbage", f"numerics/{kind} {method}: non-finite parameters, exit 0"
    err = _nrmse(res.structure.torques(res.parameters, tr), tr.tau)
    if err > max(2 * ctx["clean_nrmse"], ctx["clean_nrmse"] + 0.05) and not caught:
        return "garbage", (f"numerics/{kind} {method}: model NRMSE on the clean log {100 * err:.1f} % "
                           f"(clean fit {100 * ctx['clean_nrmse']:.1f} %), no error or warning")
    return "ok", ""

"""Friction state on simulated bench joints: error near reversals, state vs best static law.

For each seed and each true joint (:mod:`sensorless_studies.simulation.lugre`: LuGre joints with several
presliding stiffnesses and micro-dampings, and a static joint without the effect) a training log
and a held-out log with another random velocity profile are simulated (irregular steps, noise),
a :class:`~sensorless.identification.friction_model.FrictionModel` is fitted (``state="auto"``),
and the held-out RMSE near reversals (:func:`~sensorless.identification.friction_model.reversal_mask`,
± 1 s) of the chosen law and of the best static law are recorded with the choice (blocked held-out
error; the BIC of both is kept).
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["TRUTHS", "bench_friction_state"]

#: name -> LuGre parameters (sigma0=None: the static limit, a joint without presliding or hysteresis)
TRUTHS = {
    "lugre": {},
    "lugre_stiff": {"sigma0": 1000.0, "sigma1": 2.0},
    "lugre_soft_damped": {"sigma0": 60.0, "sigma1": 3.0, "vs": 0.05},
    "static": {"sigma0": None},
}


def bench_friction_state(seeds: int = 5, *, train_seconds: float = 60.0, test_seconds: float = 40.0,
                         console=None) -> dict:
    """Figures per truth and seed (module docstring); JSON-able."""
    from sensorless.identification.friction_model import FrictionModel, friction_errors
    from ..simulation.lugre import LuGreJoint, lugre_friction, simulate_lugre_joint, velocity_profile

    out = {"seeds": seeds, "train_seconds": train_seconds, "test_seconds": test_seconds, "truths": {}}
    for name, params in TRUTHS.items():
        truth = LuGreJoint(**params)
        rows = []
        for seed in range(seeds):
            t0 = time.perf_counter()
            train, _ = simulate_lugre_joint(truth, duration=train_seconds, seed=seed)
            prof = velocity_profile(test_seconds, 1000 + seed)
            test, _ = simulate_lugre_joint(truth, duration=test_seconds, seed=1000 + seed, profile=prof)
            model = FrictionModel().fit([train])
            f_true = lugre_friction(truth, prof, test.t)[0] + truth.inertia * prof(test.t)[2] + truth.offset
            v_true = prof(test.t)[1]
            law = model.laws_["joint"]
            e = {kind: friction_errors(test.tau[:, 0], model.predict(test, static=kind == "static")[:, 0], test.t,
                                       v_true, threshold=1e-3)
                 for kind in ("model", "static")}
            e_true = {kind: float(np.sqrt(np.mean((model.predict(test, static=kind == "static")[:, 0] - f_true) ** 2)))
                      for kind in ("model", "static")}
            rows.append({"seed": seed, "chosen": law.kind, "bic": model.fits_["joint"].bic["static"],
                         "bic_state": model.fits_["joint"].bic["state"],
                         "presliding_distance": law.presliding_distance,
                         "rmse_reversals": e["model"]["rmse_reversals"], "rmse_reversals_static": e["static"]["rmse_reversals"],
                         "ratio_reversals": e["model"]["rmse_reversals"] / e["static"]["rmse_reversals"],
                         "rmse": e["model"]["rmse"], "rmse_static": e["static"]["rmse"],
                         "rmse_vs_true_friction": e_true["model"], "rmse_vs_true_friction_static": e_true["static"],
                         "seconds": time.perf_counter() - t0})
            if console is not None:
                r = rows[-1]
                console.print(f"{name} seed {seed}: {r['chosen']}, near reversals {r['rmse_reversals']:.4g} vs static "
                              f"{r['rmse_reversals_static']:.4g} N·m (ratio {r['ratio_reversals']:.3f})")
        ratios = [r["ratio_reversals"] for r in rows]
        out["truths"][name] = {"params": {k: getattr(truth, k) for k in ("fc", "fs", "vs", "sigma0", "sigma1",
                                                                           "sigma2", "inertia")},
                               "chosen_state": sum(r["chosen"] == "state" for r in rows),
                               "max_ratio_reversals": max(ratios), "median_ratio_reversals": float(np.median(ratios)),
                               "runs": rows}
    return out

"""Simulated dVRK PSM logs in the WPI format (free motion, palpation, payload pair), for docs/surgical-arm.md."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write"]

#: the payload of loaded.csv: a point mass on the instrument link, CoM along the shaft
PAYLOAD = {"frame": "pitch_end", "mass_kg": 0.2, "com_m": [0.0, 0.0, 0.3]}
NOISE = 0.003  # effort noise [N·m, N]
SMOOTHING = 0.2  # Coulomb smoothing ε [rad/s] of the true drives (the value cross-validated on the WPI logs)


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    import numpy as np
    import pinocchio as pin

    from ..experiments.psm_identification import paired_payload_logs, write_psm_csv
    from ..simulation.psm_logs import palpation_force, psm_motion, psm_truth, tip_force_efforts

    rng = np.random.default_rng(seed)
    s, p = psm_truth(rng, coulomb_smoothing=SMOOTHING)
    long, short = (30.0, 20.0) if full else (15.0, 6.0)

    def log(k: int, duration: float):
        mot = psm_motion(seed * 10 + k, duration, rate=200.0)
        return mot, s.evaluate(mot.q, mot.v, mot.a) @ p + rng.normal(size=(len(mot), 7)) * NOISE

    mot, tau = log(1, long)
    write_psm_csv(mot.with_(tau=tau), out / "free.csv")
    mot, tau = log(2, short)
    F = palpation_force(mot.t, rng=rng)
    write_psm_csv(mot.with_(tau=tau + tip_force_efforts(s, mot, F)), out / "palpation.csv")
    np.savetxt(out / "palpation_force.csv", np.column_stack([mot.t, F]), delimiter=",", fmt="%.6g",
               header="t,fx,fy,fz", comments="")
    payload = pin.Inertia(PAYLOAD["mass_kg"], np.array(PAYLOAD["com_m"]), np.zeros((3, 3)))
    unloaded, loaded = paired_payload_logs(s, p, psm_motion(seed * 10 + 3, long, rate=200.0), payload, PAYLOAD["frame"],
                                           noise_std=np.full(7, NOISE), seed=seed)
    write_psm_csv(unloaded, out / "unloaded.csv")
    write_psm_csv(loaded, out / "loaded.csv")
    truth = {"payload": PAYLOAD, "palpation_force": "palpation_force.csv (N, the tip on the environment, world axes)",
             "effort_noise": NOISE, "coulomb_smoothing": SMOOTHING, "rate_hz": 200.0,
             "columns": "q=0:7;v=7:14;tau=14:21 (coordinates q1 q2 q3 q4 m5 m6 m7)", "seed": seed, "full": full}
    (out / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    return ["free.csv", "palpation.csv", "palpation_force.csv", "unloaded.csv", "loaded.csv", "truth.json"]

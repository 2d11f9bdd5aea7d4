"""UR10 runs with currents for drive-gains and payload: cal0.csv, cal4kg.csv, pay0.csv, pay.csv, truth.json."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write", "CAL_MASS", "CAL_COM", "PAY_MASS", "PAY_COM"]

#: the calibration mass [kg] and its CoM [m] in ``tool0`` (off the tool axis: it loads the last joint too)
CAL_MASS, CAL_COM = 4.0, (0.15, 0.05, 0.05)
#: the payload ``sensorless payload`` is to find
PAY_MASS, PAY_COM = 2.5, (0.02, -0.03, 0.08)


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    """A perturbed "true" UR10 with Stribeck friction logging motor currents at a jittery 100 Hz
    (:func:`sensorless_studies.simulation.current_arm.simulate`, columns ``time, pos_J, vel_J, i_J``):
    one trajectory without (``cal0.csv``) and with ``CAL_MASS`` at ``CAL_COM`` on tool0
    (``cal4kg.csv``), another without (``pay0.csv``) and with ``PAY_MASS`` at ``PAY_COM``
    (``pay.csv``); each run 2 s idle, the motion (10 s, 20 s with ``full``), 3 s idle.
    ``truth.json`` holds the true gains and masses."""
    from ..simulation.current_arm import drive_gains_for, simulate, truth_model, with_payload

    robot, truth = truth_model("ur10", seed, stribeck=True, friction_scale=4.0)
    K = drive_gains_for(robot)
    motion = 20.0 if full else 10.0
    base = 100 * seed
    runs = {"cal0": (truth, base + 1, base + 10), "cal4kg": (with_payload(truth, "tool0", CAL_MASS, CAL_COM), base + 2,
                                                             base + 10),
            "pay0": (truth, base + 3, base + 20), "pay": (with_payload(truth, "tool0", PAY_MASS, PAY_COM), base + 4,
                                                          base + 20)}
    for name, (tr, s, ms) in runs.items():
        simulate(robot, tr, K, seed=s, motion_seed=ms, motion=motion).to_csv(out / f"{name}.csv", index=False)
    (out / "truth.json").write_text(json.dumps({
        "gains": dict(zip(robot.actuated_joints, map(float, K))), "frame": "tool0",
        "calibration": {"mass": CAL_MASS, "com": list(CAL_COM)}, "payload": {"mass": PAY_MASS, "com": list(PAY_COM)},
    }, indent=1))
    return [f"{n}.csv" for n in runs] + ["truth.json"]

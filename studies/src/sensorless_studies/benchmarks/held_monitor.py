"""Held-still arm monitoring (issue 27, item 4) over seeds, through the CLI.

Per seed: :func:`~sensorless_studies.simulation.held_arm.held_arm_scenario` (a UR5 with stiction, PD
position loop, held still for 60 s at 500 Hz and pushed 5 times; a 30 s tracking log to
identify it), then the documented commands with the defaults::

    sensorless identify --robot ur5 --data train.npz --out id --no-plot
    sensorless monitor --robot ur5 --model id --data held.npz --frame tool0 --out mon [--order 2]

and, for comparison, the same monitor without the dead zone (``--static-friction off``).
Scored: pushes found, false alarms per minute of contact-free log (an interval that overlaps
no push ± 0.2 s), the RMS force reported while every joint is stuck and no push is on against
the noise-implied force (torque noise through (Jᵀ)⁺), the share of the log flagged, and the
first alarm.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["run"]


def _cli(args: list) -> None:
    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.errors import SensorlessError

    r = CliRunner().invoke(app, [str(a) for a in args])
    if r.exit_code != 0:
        raise SensorlessError(f"sensorless {' '.join(map(str, args[:1]))} failed: {r.output[-2000:]}")


def _score(out: Path, sc) -> dict:
    from sensorless.estimation.collision import ContactInterval, score_detection

    doc = json.loads((out / "monitor.json").read_text())
    arr = np.load(out / "monitor.npz")
    t = arr["t"] - arr["t"][0]
    ivs = [ContactInterval(c["start_s"], c["end_s"], c["start_index"], c["end_index"], c["peak"], c["peak_time"],
                           c["joints"]) for c in doc["contacts"]]
    s = score_detection(ivs, t, sc.truth.active)
    rest = float(np.sqrt(np.mean(np.sum(arr["force"][sc.still] ** 2, axis=1))))
    return {"pushes": s["contacts"], "found": s["detected"], "false_alarms": s["false_alarms"],
            "false_alarms_per_minute": s["false_alarms_per_minute"], "mean_delay_s": s["mean_delay_s"],
            "rest_force_rms": rest, "noise_implied_force": sc.noise_force, "rest_force_ratio": rest / sc.noise_force,
            "contact_fraction": doc["contact_fraction"],
            "first_alarm_s": min((c["start_s"] for c in doc["contacts"]), default=None)}


def run(seeds: int = 10, first_seed: int = 0) -> dict:
    """Score ``seeds`` scenarios (module docstring); JSON-able."""
    from sensorless.data import write_npz
    from ..simulation.held_arm import held_arm_scenario

    out: dict = {"seeds": [], "commands": ["identify --robot ur5 --data train.npz --out id --no-plot",
                                           "monitor --robot ur5 --model id --data held.npz --frame tool0 [--order 2]"]}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(first_seed, first_seed + seeds):
            d = Path(tmp) / f"seed{seed}"
            d.mkdir()
            sc = held_arm_scenario(seed)
            write_npz(sc.train, d / "train.npz")
            write_npz(sc.log, d / "held.npz")
            _cli(["identify", "--robot", "ur5", "--data", d / "train.npz", "--out", d / "id", "--no-plot"])
            row = {"seed": seed}
            for name, extra in (("order1", []), ("order2", ["--order", "2"]), ("no_dead_zone", ["--static-friction", "off"])):
                _cli(["monitor", "--robot", "ur5", "--model", d / "id", "--data", d / "held.npz", "--frame", "tool0",
                      "--out", d / name, *extra])
                row[name] = _score(d / name, sc)
            out["seeds"].append(row)
    for name in ("order1", "order2", "no_dead_zone"):
        rows = [r[name] for r in out["seeds"]]
        out[name] = {"all_pushes_found": all(r["found"] == r["pushes"] for r in rows),
                     "max_false_alarms_per_minute": max(r["false_alarms_per_minute"] for r in rows),
                     "max_rest_force_ratio": max(r["rest_force_ratio"] for r in rows),
                     "mean_contact_fraction": float(np.mean([r["contact_fraction"] for r in rows])),
                     "earliest_alarm_s": min((r["first_alarm_s"] for r in rows if r["first_alarm_s"] is not None),
                                             default=None)}
    out["wall_s"] = time.perf_counter() - t0
    return out

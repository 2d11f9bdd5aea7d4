"""UR10 run pairs started 1.2 s apart, with corrupt rows: cal_*.csv, pay_*.csv, for docs/arm.md §8."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write", "write_logs", "LAG", "CAL_MASS", "CAL_COM"]

LAG = 1.2  # [s] the loaded runs start their excitation this much later
CAL_MASS, CAL_COM = 4.0, (0.15, 0.05, 0.05)
_RUN = dict(motion=10.0, idle_end=1.0, ramp=1.0)
_IDLE = 1.5


def write_logs(work: Path, seed: int = 0) -> dict:
    """The four runs of one seed as CSV files in ``work``; returns the truth (robot, gains, payload).

    A "true" UR10 with Stribeck friction logging currents at a jittery 100 Hz
    (:func:`~sensorless_studies.simulation.current_arm.simulate`); two pairs of runs of one trajectory each,
    the loaded run starting ``LAG`` s after the unloaded one, its file with 9 corrupt leading rows and
    a last row cut after 11 fields (:func:`~sensorless_studies.simulation.log_faults.write_faulty_csv`):
    ``cal_unloaded.csv`` / ``cal_loaded.csv`` (``CAL_MASS`` at ``CAL_COM`` on tool0) and
    ``pay_unloaded.csv`` / ``pay_loaded.csv`` (m ~ U(2, 3) kg at an unknown CoM)."""
    from ..simulation.current_arm import drive_gains_for, simulate, truth_model, with_payload
    from ..simulation.log_faults import write_faulty_csv

    robot, truth = truth_model("ur10", seed, stribeck=True, friction_scale=4.0)
    K = drive_gains_for(robot)
    rng = np.random.default_rng(20_000 + seed)
    m_pay = float(rng.uniform(2.0, 3.0))
    com_pay = (float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-0.05, 0.05)), float(rng.uniform(0.03, 0.1)))
    work.mkdir(parents=True, exist_ok=True)
    base = 1000 * seed
    for pair, load, ms in (("cal", with_payload(truth, "tool0", CAL_MASS, CAL_COM), base + 30),
                           ("pay", with_payload(truth, "tool0", m_pay, com_pay), base + 50)):
        simulate(robot, truth, K, seed=ms, idle_start=_IDLE, motion_seed=ms, **_RUN).to_csv(
            work / f"{pair}_unloaded.csv", index=False)
        loaded = simulate(robot, load, K, seed=ms + 1, idle_start=_IDLE + LAG, motion_seed=ms, **_RUN)
        write_faulty_csv(loaded, work / f"{pair}_loaded.csv", leading=9, cut_after=11, seed=seed)
    return {"robot": robot, "gains": K, "mass": m_pay, "com": com_pay}


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    write_logs(Path(out), seed)
    return ["cal_unloaded.csv", "cal_loaded.csv", "pay_unloaded.csv", "pay_loaded.csv"]

"""Position-controlled TALOS leg logs (1 kHz: q, q_cmd, current, ankle F/T, IMU) of the three actuator protocols, for docs/position-controlled.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write"]


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    from ..experiments.torque_control import StudyConfig, identification_logs
    from sensorless.io import write_npz_atomic
    from ..simulation.leg_model import JOINTS

    cfg = StudyConfig(ident_seconds=40.0 if full else 5.0)  # seconds per protocol (the study's full size: 40)
    names = []
    for protocol, (log, _) in identification_logs(cfg, seed).items():
        write_npz_atomic(out / f"{protocol}.npz", t=log.t, q=log.q, q_cmd=log.q_cmd, current=log.current, ft=log.ft,
                         gyro=log.gyro, acc=log.acc, tau_true=log.tau, joint_names=np.array(JOINTS))
        names.append(f"{protocol}.npz")
    return names

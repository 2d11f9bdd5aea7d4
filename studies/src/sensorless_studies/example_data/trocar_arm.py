"""Simulated RCM arm in a trocar (URDF, free-space, in-port and palpation logs), for docs/surgical-arm.md."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write"]

#: seconds of each log (quick); ``full`` uses the study's full durations (sensorless_studies.simulation.trocar.DURATIONS)
QUICK = {"free_space": 20.0, "split": 0.5, "trocar_multisine": 30.0, "trocar_probe": 60.0, "trocar_test": 10.0, "contact": 10.0}


def write(out: Path, *, full: bool = False, seed: int = 0) -> list[str]:
    import numpy as np

    from sensorless.data import write_npz
    from sensorless.export import write_urdf
    from ..simulation.trocar import make_datasets

    d = make_datasets(seed, quick=False, durations=None if full else QUICK)
    robot = d.robot  # the nominal (CAD) arm; the simulated one differs (±15 % masses, CoMs, friction)
    write_urdf(robot, robot.inertial_parameters(), out / "psm_like.urdf", frames=True)
    logs = {"free.npz": d.free_space, "port_1.npz": d.trocar_train[0], "port_2.npz": d.trocar_train[1],
            "port_test.npz": d.trocar_test[0], "contact.npz": d.trocar_contact}
    for name, log in logs.items():
        write_npz(log, out / name)
    c = d.trocar_contact
    np.savetxt(out / "contact_force.csv", np.column_stack([c.t, c.extras["f_tip"]]), delimiter=",", fmt="%.6g",
               header="t,fx,fy,fz", comments="")
    return ["psm_like.urdf", *logs, "contact_force.csv"]

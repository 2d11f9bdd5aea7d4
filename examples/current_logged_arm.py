"""Simulated logs of an arm with no torque sensor: motor currents, a jittery ~100 Hz clock,
and idle segments at the start and the end. Used by docs/arm.md ("Logs of motor currents").

    python examples/current_logged_arm.py OUTDIR [--robot ur5] [--seed 0] [--stribeck] [--payload KG]

writes OUTDIR/train.csv and OUTDIR/test.csv (two different excitation trajectories of
the same "true" robot) and OUTDIR/gains.json (the drive gains, joint -> K [N·m/A]).
``--stribeck`` gives the true robot Stribeck friction (:class:`StribeckTruth`);
``--payload KG`` also writes OUTDIR/loaded.csv, the train trajectory run again (new
clock jitter and noise) with a point mass at (0.06, 0.02, 0.05) m in the tool frame, for ``sensorless drive-gains``.

Each CSV has a header ``time, pos_<joint>..., vel_<joint>..., i_<joint>...``:

* time: Unix-epoch seconds, nominal 100 Hz, each stamp off by N(0, (0.15 T)²) and a
  few stamps repeated (as a logger that reads the clock late does);
* pos/vel: the true joint positions and velocities at those instants, plus encoder and
  velocity-estimate noise; no accelerations are logged;
* i: motor currents i = τ / K + noise, τ from Pinocchio's RNEA on a perturbed "true"
  model plus friction, offsets and rotor inertia (:func:`sensorless.simulation.perturbed_truth`);
* the robot rests ``idle_start`` s before and ``idle_end`` s after the motion, which
  blends in and out of a Fourier excitation with a quintic ramp (smooth q, v, v̇).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sensorless.simulation.current_arm import (  # noqa: F401 (the tests and docs use them from here)
    UR5_GAINS,
    StribeckTruth,
    drive_gains_for,
    simulate,
    stribeck_truth,
    truth_model,
    with_payload,
)

def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--robot", default="ur5")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--stribeck", action="store_true", help="Stribeck friction in the true robot")
    p.add_argument("--payload", type=float, default=None, help="also write loaded.csv: train run with KG at tool0")
    args = p.parse_args(argv)
    robot, truth = truth_model(args.robot, args.seed, stribeck=args.stribeck)
    gains = drive_gains_for(robot)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, seed in (("train", args.seed + 1), ("test", args.seed + 2)):
        simulate(robot, truth, gains, seed=seed).to_csv(args.out / f"{name}.csv", index=False)
    if args.payload:
        loaded = with_payload(truth, "tool0", args.payload)
        simulate(robot, loaded, gains, seed=args.seed + 3, motion_seed=args.seed + 1).to_csv(args.out / "loaded.csv",
                                                                                              index=False)
    (args.out / "gains.json").write_text(json.dumps(dict(zip(robot.joint_names, map(float, gains))), indent=1))
    print(f"wrote {args.out}/train.csv, test.csv{', loaded.csv' if args.payload else ''}, gains.json "
          f"({robot.name}, {robot.n_actuated} joints)")

if __name__ == "__main__":
    main()

"""Issue 39 item 3: the gain check knows friction and rest (a held-still or friction-dominated joint with
correct gains is never refused; a gain in the wrong unit still is, naming the joint and the comparison)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.data.plausibility import check_gain_plausibility, model_torque_bounds
from sensorless.data.trajectory import Trajectory
from sensorless.errors import UnitsError
from sensorless.testing import (RealArtefacts, one_joint_at_a_time, perturbed_truth, synthetic_trajectory,
                                with_real_artefacts)


def _held_still_log(robot, q0, amplitude, gain=10.0, duration=60.0):
    """One joint at a time, small sweeps, the others held (holding current up to 3 N·m), logged to 4 decimals;
    the torques as a lab computes them from currents with the gain ``gain`` (here: the true one, 10)."""
    truth = perturbed_truth(robot, rng=1)
    t = np.arange(0, duration, 0.005)
    q, v, a = one_joint_at_a_time(t, np.asarray(q0, float), amplitude=amplitude, period=8.0)
    log = synthetic_trajectory(truth, Trajectory(t=t, q=q, v=v, a=a, joint_names=robot.joint_names, source="<1j>"),
                               noise_std=0.01, rng=0)
    log = with_real_artefacts(log, RealArtefacts(holding=3.0, decimals=4), rng=0)
    return log.with_(tau=log.tau * gain / 10.0,
                     provenance=dict(log.provenance, gains={j: gain for j in robot.joint_names}))


UPRIGHT = [0.0, -1.5708, 0.0, -1.5708, 0.0, 0.0]  # the UR5 pointing up: gravity loads no joint


def test_an_upright_arm_held_still_with_correct_gains_passes(ur5):
    """Regression (the UR10e single-joint logs): every joint of an upright arm carries friction and holding
    current only; the rigid-body model predicts ~0 N·m, and the old check refused shoulder_pan at 363×."""
    log = _held_still_log(ur5, UPRIGHT, 0.05)
    rigid, friction, _, _ = model_torque_bounds(log, ur5)
    assert rigid[0] < 0.05 and np.all(friction > 1.0)  # the case: no rigid-body torque, friction can be large
    check_gain_plausibility(log, ur5)  # no error


@pytest.mark.parametrize("factor", [1e3, 1e-3])
def test_a_gain_in_the_wrong_unit_is_still_refused_naming_the_joint(ur5, factor):
    """mN·m/A read as N·m/A (×1000) on the same upright log, or a gain 1000× too small on a loaded arm."""
    q0 = UPRIGHT if factor > 1 else [0.0, -0.3, 0.8, -1.0, 0.0, 0.0]  # the loaded case: the arm stretched out
    log = _held_still_log(ur5, q0, 0.6, gain=10.0 * factor)
    with pytest.raises(UnitsError, match=r"joint '\w+': drive gain .*(most the robot model|while the joint moves)"):
        check_gain_plausibility(log, ur5)


def test_friction_dominated_log_with_correct_gains_exits_0_without_override(ur5, tmp_path):
    """The acceptance case end to end: `sensorless identify` on currents of the upright, held-still arm with the
    right gains and no override flag (the old check refused it: "a gain in the wrong unit?")."""
    import pandas as pd
    from typer.testing import CliRunner

    from sensorless.cli import app

    log = _held_still_log(ur5, UPRIGHT, 0.05)
    cols = {"t": log.t, **{f"q_{n}": log.q[:, j] for j, n in enumerate(log.joint_names)},
            **{f"i_{n}": log.tau[:, j] / 10.0 for j, n in enumerate(log.joint_names)}}
    pd.DataFrame(cols).to_csv(tmp_path / "currents.csv", index=False)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "currents.csv"),
                                 "--columns", "q=q_{joint};tau=i_{joint}", "--gains", "10", "--gamma", "1e-3",
                                 "--joint-terms", "fv,fc,offset", "--out", str(tmp_path / "m"), "--no-plot"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "m" / "result.json").exists()

"""Issue 40: a channel's quantization step and rounding, read from the log itself, floor its noise (a UR logs q
and v to 4 decimals: a joint held still had a velocity noise of 1e-26 rad/s and was rarely at rest)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import Trajectory, prepare
from sensorless.data.resolution import channel_resolution, noise_floor
from sensorless.data.rest import signal_noise
from sensorless.testing import RealArtefacts, with_real_artefacts

RNG = np.random.default_rng(0)
T = np.arange(5000) / 500.0
SMOOTH = 0.3 * np.sin(T) + 1e-5 * RNG.normal(size=T.size)


@pytest.mark.parametrize("x, step, decimals", [
    (SMOOTH, 0.0, None),  # continuous
    (np.round(SMOOTH, 4), 1e-4, 4),  # written to 4 decimals
    (np.round(SMOOTH, 4).astype(np.float32), 1e-4, 4),  # ... in a float32 file
    (np.round(SMOOTH / 2.5e-4) * 2.5e-4, 2.5e-4, 5),  # a height sensor's 0.25 mm quanta
    (np.round(1000 * SMOOTH), 1.0, 0),  # integer ticks
    (3e-4 * RNG.normal(size=2000), 0.0, None),  # a continuous signal smaller than one unit of a low decimal
    (np.full(200, 1.5), 0.0, None),  # a constant says nothing
])
def test_the_step_and_decimals_are_read_from_the_samples(x, step, decimals):
    r = channel_resolution(x)
    assert r.decimals == decimals
    np.testing.assert_allclose(r.step, step, rtol=1e-3)
    np.testing.assert_allclose(noise_floor(x), [step / np.sqrt(12)], rtol=1e-3)


def _held_arm(decimals=4, seconds=20.0, rate=250.0, seed=0):
    """Six joints held still (true noise far below the last decimal) with one joint moving slowly in the middle."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    q0 = np.array([0.1234, -1.57, 1.2, -0.8, 1.57, 0.3])
    q = q0 + 2e-6 * rng.normal(size=(t.size, 6))
    v = 2e-5 * rng.normal(size=(t.size, 6))
    move = (t > 8) & (t < 12)
    q[:, 2] += np.where(move, 0.2 * (1 - np.cos(np.pi * (t - 8) / 2)), np.where(t >= 12, 0.0, 0.0))
    v[:, 2] += np.where(move, 0.2 * np.pi / 2 * np.sin(np.pi * (t - 8) / 2), 0.0)
    names = tuple(f"j{k}" for k in range(6))
    traj = Trajectory(t=t, q=q, v=v, tau=np.zeros_like(q), joint_names=names)
    return with_real_artefacts(traj, RealArtefacts(decimals=decimals), rng)


def test_a_held_still_arm_logged_to_4_decimals_is_at_rest_with_a_noise_of_one_quantum():
    traj = _held_arm()
    assert np.median(signal_noise(traj.v)) >= 1e-4 / np.sqrt(12)  # was ~1e-26: the MAD of a constant
    out = prepare(traj)
    assert out.provenance["resolution"]["v"]["j0"] == {"step": pytest.approx(1e-4), "decimals": 4}
    rest = out.provenance["rest"]
    for j in ("j0", "j1", "j3", "j4", "j5"):
        assert rest["velocity_noise"][j] >= 1e-4 / np.sqrt(12) * 0.999
        assert rest["fraction_at_rest"][j] > 0.99, rest
    assert rest["fraction_at_rest"]["j2"] < 0.9  # the moving joint is not


def test_identify_writes_the_detected_resolution_to_result_json(tmp_path):
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory
    from sensorless.excitation import random_fourier

    ur5 = load_robot("ur5")
    truth = perturbed_truth(ur5, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(ur5, rng=1).sample(100, 10.0), noise_std=0.05, rng=2)
    tr = with_real_artefacts(tr, RealArtefacts(decimals=4, q_step=2e-4), 3)
    cols = {f"pos_{j}": tr.q[:, k] for k, j in enumerate(ur5.actuated_joints)}
    cols |= {f"vel_{j}": tr.v[:, k] for k, j in enumerate(ur5.actuated_joints)}
    cols |= {f"tau_{j}": tr.tau[:, k] for k, j in enumerate(ur5.actuated_joints)}
    path = tmp_path / "log.csv"
    import pandas as pd

    pd.DataFrame({"time": tr.t, **cols}).to_csv(path, index=False)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(path), "--method", "ols", "--columns",
                                 "q=pos_{joint};v=vel_{joint};tau=tau_{joint}", "--no-plot", "--out",
                                 str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    res = json.loads((tmp_path / "m" / "result.json").read_text())["settings"]["signals"][str(path)]["resolution"]
    j = ur5.actuated_joints[0]
    assert res["q"][j]["step"] == pytest.approx(2e-4) and res["q"][j]["decimals"] == 4
    assert res["v"][j]["decimals"] == 4 and "tau" not in res

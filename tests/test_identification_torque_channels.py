"""Torque channels checked before the fit: constant, zero, dead while moving, or off in scale (units)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.errors import DataError, UnitsError
from sensorless.excitation import random_fourier
from sensorless.identification import identify
from sensorless.testing import perturbed_truth, synthetic_trajectory


@pytest.fixture(scope="module")
def log(request):
    panda = request.getfixturevalue("panda")
    truth = perturbed_truth(panda, rng=0)
    motion = random_fourier(panda, rng=3, base_freq=0.1).sample(100.0, 10.0)
    return panda, synthetic_trajectory(truth, motion, noise_std=0.01, rng=7)


def _with_tau(traj, j, column):
    tau = traj.tau.copy()
    tau[:, j] = column
    return traj.with_(tau=tau)


@pytest.mark.parametrize("kind", ["zero", "constant"])
def test_constant_or_zero_channel_names_the_joint(log, kind):
    robot, traj = log
    bad = _with_tau(traj, 3, 0.0 if kind == "zero" else 2.5)
    with pytest.raises(DataError, match=rf"joint '{robot.joint_names[3]}'.*{kind}"):
        identify(robot, bad, weights=None)


def test_channel_dead_while_its_joint_moves(log):
    robot, traj = log
    col = traj.tau[:, 5].copy()
    col[300:600] = col[300]  # the sensor holds one value for 3 s while the joint keeps moving
    with pytest.raises(DataError, match=rf"joint '{robot.joint_names[5]}'.*holds .* while the joint moves"):
        identify(robot, _with_tau(traj, 5, col), weights=None)


@pytest.mark.parametrize("scale", [1e6, 1e3, 1e-3])
def test_every_channel_scaled_is_a_units_error(log, scale):
    robot, traj = log
    with pytest.raises(UnitsError, match=r"joint '.*'.*× what the prior model predicts"):
        identify(robot, traj.with_(tau=traj.tau * scale), weights=None)


def test_one_channel_scaled_names_that_joint(log):
    robot, traj = log
    with pytest.raises(UnitsError, match=rf"joint '{robot.joint_names[1]}'"):
        identify(robot, _with_tau(traj, 1, traj.tau[:, 1] * 1e-3), weights=None)


def test_sound_log_passes_and_the_check_can_be_skipped(log):
    robot, traj = log
    res = identify(robot, traj, weights=None)
    assert np.all(np.isfinite(res.parameters))
    res = identify(robot, traj.with_(tau=traj.tau * 1e3), weights=None, check_torques=False)
    assert np.all(np.isfinite(res.parameters))  # the user said the scale is right


def test_massless_prior_gives_no_scale_and_is_not_refused():
    from sensorless.cli.common import load_robot_arg

    psm = load_robot_arg("dvrk_psm", None, None)
    s = psm.make_structure("authors")
    motion = random_fourier(psm, rng=1, base_freq=0.1).sample(100.0, 10.0)
    rng = np.random.default_rng(0)
    traj = motion.with_(tau=rng.normal(size=(len(motion), len(motion.joint_names))) * 0.2)
    from sensorless.identification.torque_channels import TorqueChannels, check_torque_channels

    ch = TorqueChannels(s)
    ch.add(traj)
    assert ch.rows == tuple(s.row_names) and ch.n_sub > 0 and not ch.ss_prior.any()
    check_torque_channels(ch)  # random but live channels, and no prior scale: nothing to refuse


def test_cli_refuses_scaled_torques_naming_the_joint_unless_accepted(log, tmp_path):
    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.data import write_npz

    robot, traj = log
    write_npz(traj.with_(tau=traj.tau * 1e6), tmp_path / "mNm.npz")
    args = ["identify", "--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2",
            "--data", str(tmp_path / "mNm.npz"), "--method", "ols", "--joint-terms", "fv,fc,offset", "--no-plot"]
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert res.exit_code == 2 and "panda_joint" in res.output and "--accept-implausible-torques" in res.output
    assert not (tmp_path / "a").exists()
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "c"), "--accept-implausible"])
    assert res.exit_code == 2 and "--accept-implausible-torques" in res.output  # each override its own check
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "b"), "--accept-implausible-torques",
                                   "--accept-implausible"])  # mN·m: the model is implausible too
    assert res.exit_code == 0, res.output
    assert (tmp_path / "b" / "result.json").exists()


def test_a_reversed_sign_names_the_joint(log):
    robot, traj = log
    with pytest.raises(DataError, match=rf"joint '{robot.joint_names[1]}'.*reversed sign"):
        identify(robot, _with_tau(traj, 1, -traj.tau[:, 1]), weights=None)


def test_swapped_columns_name_the_joint(log):
    robot, traj = log
    tau = traj.tau.copy()
    tau[:, [1, 3]] = tau[:, [3, 1]]
    with pytest.raises(DataError, match=r"swapped columns"):
        identify(robot, traj.with_(tau=tau), weights=None)

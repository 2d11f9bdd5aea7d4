"""Floating base from measured contact wrenches (issue 11, item 3): base rows only, constant
wrench bias, world-axis base-wrench metrics, identified mass/CoM, CoM-vs-CoP, (N, feet, 6)
wrench files, and regression tests for each failure reported on a humanoid walking log."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import read_trajectory, write_npz
from sensorless.errors import DataError, RobotModelError
from sensorless.identification import identify
from sensorless.identification.floating_base import base_wrench_metrics, com_cop_check, com_positions
from sensorless.regressor import ContactStructure
from sensorless.regressor.contact import choose_contact_rows
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth
from sensorless_studies.simulation.wrench_log import walking_flags, wrench_log

FEET = ("left_sole_link", "right_sole_link")
BIAS = np.array([[30.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # 30 N horizontal on the left sole


@pytest.fixture(scope="module")
def legs():
    return load_robot("talos_legs")


@pytest.fixture(scope="module")
def truth(legs):
    return perturbed_truth(legs, rng=3)


@pytest.fixture(scope="module")
def log(truth):
    """Walking-like contact pattern, sole-frame bias, no joint torques."""
    return wrench_log(truth.robot, FEET, duration=6.0, flags=walking_flags(600, 2, 80), bias=BIAS, seed=1)


def _structure(robot, **kw):
    kw.setdefault("contact_rows", "base")
    return ContactStructure(robot, contact_frames=FEET, contact_dims=(6, 6), mode="wrench", joint_terms=(), **kw)


def _mass_com(robot, inertial):
    Q = pin.neutral(robot.model)[None]
    return float(np.reshape(inertial, (-1, 10))[:, 0].sum()), com_positions(robot, inertial, Q)[0]


def test_base_rows_recover_mass_com_and_sole_offset_with_a_biased_wrench(legs, truth, log):
    m_true, c_true = _mass_com(truth.robot, truth.robot.inertial_parameters())
    s = _structure(legs, wrench_offset="sole")
    res = identify(s, log)
    m, c = _mass_com(legs, res.inertial_parameters)
    assert abs(m - m_true) < 1e-6 * m_true
    assert np.linalg.norm(c - c_true) < 1e-6
    bias = s.offset_values(res.parameters)
    assert bias["left_sole_link"]["fx"] == pytest.approx(30.0, abs=1e-6)
    assert abs(bias["left_sole_link"]["fy"]) < 1e-6 and abs(bias["right_sole_link"]["fx"]) < 1e-6
    # result.json reports the identified mass and CoM, not the model file's
    mp = res.to_dict()["mass_properties"]
    assert mp["total_mass"] == pytest.approx(m_true, rel=1e-6)
    np.testing.assert_allclose(mp["com"], c_true, atol=1e-6)
    assert abs(mp["urdf_total_mass"] - m_true) > 0.01 * m_true  # the prior differs: the check can fail


def test_without_the_offset_the_bias_moves_the_com(legs, truth, log):
    """Regression: no offset term → the 30 N bias shifts the CoM by centimetres."""
    _, c_true = _mass_com(truth.robot, truth.robot.inertial_parameters())
    res = identify(_structure(legs), log)
    _, c = _mass_com(legs, res.inertial_parameters)
    assert np.linalg.norm(c - c_true) > 0.01


@pytest.mark.parametrize("kind,frame", [("foot", "world"), ("net", "world")])
def test_world_axis_offsets_recovered(legs, truth, kind, frame):
    bias = np.array([[12.0, -7.0, 0.0], [12.0, -7.0, 0.0]]) if kind == "net" else np.array([[20.0, 5.0, 0], [-8, 3, 0]])
    lg = wrench_log(truth.robot, FEET, duration=4.0, flags=np.ones((400, 2), bool), bias=bias, bias_frame=frame, seed=2)
    s = _structure(legs, wrench_offset=kind)
    res = identify(s, lg)
    vals = s.offset_values(res.parameters)
    if kind == "net":  # the net bias is the sum over the (always two) active feet
        assert vals["net"]["fx"] == pytest.approx(24.0, abs=1e-5) and vals["net"]["fy"] == pytest.approx(-14.0, abs=1e-5)
    else:
        for k, f in enumerate(FEET):
            assert vals[f]["fx"] == pytest.approx(bias[k, 0], abs=1e-5)
            assert vals[f]["fy"] == pytest.approx(bias[k, 1], abs=1e-5)


def test_zero_or_missing_torques_in_all_rows_raise_a_typed_error(legs, log):
    """Regression: zero torques used to fit 12 joint rows to a zero target, silently."""
    s = _structure(legs, contact_rows="all")
    with pytest.raises(DataError, match="`contact_rows='base'`"):
        identify(s, log)  # no torques at all
    zeros = log.with_(tau=np.zeros_like(log.q))
    with pytest.raises(DataError, match="every joint torque is zero"):
        identify(s, zeros)
    assert choose_contact_rows([zeros])[0] == "base"
    assert choose_contact_rows([log])[0] == "base"


def test_torque_rows_come_in_when_torques_exist(legs, truth):
    lg = wrench_log(truth.robot, FEET, duration=4.0, flags=walking_flags(400, 2, 60), bias=BIAS, torques=True, seed=4)
    assert choose_contact_rows(lg)[0] == "all"
    s = ContactStructure(legs, contact_frames=FEET, contact_dims=(6, 6), mode="wrench", contact_rows="all",
                         wrench_offset="sole", joint_terms=("armature",))
    assert s.n_rows == legs.nv and s.row_names[6:] == list(legs.joint_names)
    res = identify(s, lg, method="wls")
    assert res.settings["weights"] == "auto"  # each row (base and torque) gets its own σ
    true = np.concatenate([truth.robot.inertial_parameters(), np.zeros(legs.n_actuated), BIAS[:, :2].ravel()])
    np.testing.assert_allclose(res.base_values, res.base.base(true), atol=1e-6 * np.abs(res.base.base(true)).max())


def test_base_wrench_metrics_in_world_axes(legs, truth, log):
    s = _structure(legs, wrench_offset="sole")
    res = identify(s, log)
    good = base_wrench_metrics(s, res.parameters, log)
    assert good["axes"] == "world" and good["force_rmse_norm"] < 1e-6 and good["moment_rmse_norm"] < 1e-6
    # a 1 kg mass error shows up as 9.81 N on the world z axis, whatever the base orientation
    p = res.parameters.copy()
    p[0] += 1.0  # base body mass, CoM unchanged in the other first moments
    p[1:4] += res.parameters[1:4] / res.parameters[0]
    standing = log.take(slice(0, 90))
    bad = base_wrench_metrics(s, p, standing)
    assert bad["force_rmse"][2] == pytest.approx(9.81, rel=1e-3)
    assert max(bad["force_rmse"][:2]) < 1e-6


def test_com_over_cop_on_standing_windows(legs, log):
    on = _structure(legs, wrench_offset="sole")
    check = com_cop_check(on, identify(on, log).parameters, log)
    assert check["n_samples"] > 50 and check["windows"][0][0] == 0.0
    assert check["ok"] and check["distance_mean"] < 1e-3
    off = _structure(legs)
    flagged = com_cop_check(off, identify(off, log).parameters, log)
    assert flagged["ok"] is False and flagged["distance_mean"] > 0.01


def test_contact_forces_n_feet_6_round_trip(tmp_path, log):
    """Regression: write_npz wrote (N, feet, 6) wrenches that read_trajectory rejected."""
    path = write_npz(log.with_(tau=np.zeros_like(log.q)), tmp_path / "walk.npz")
    back = read_trajectory(path)
    assert back.extras["contact_forces"].shape == (len(log), 2, 6)
    np.testing.assert_array_equal(back.extras["contact_forces"], log.extras["contact_forces"])
    np.savez(tmp_path / "bad.npz", positions=log.q, times=log.t, contact_forces=np.zeros((len(log), 2, 5)))
    with pytest.raises(DataError, match="contact_forces"):
        read_trajectory(tmp_path / "bad.npz")


def test_errors_name_the_fix(legs, log):
    urdf = legs.urdf_path
    fixed = load_robot(urdf)
    with pytest.raises(RobotModelError, match="fixed base"):  # a fixed base with contacts is fine, its 6 rows are not
        ContactStructure(fixed, contact_frames=FEET, mode="wrench", contact_rows="base")
    with pytest.raises(RobotModelError, match="mode='wrench'"):
        ContactStructure(legs, contact_frames=FEET, contact_rows="base")
    with pytest.raises(RobotModelError, match="offset_axes"):
        _structure(legs, wrench_offset="foot", offset_axes="xw")
    s = _structure(legs)
    with pytest.raises(DataError, match="contact_forces have shape"):
        s.target(log.with_(extras={**log.extras, "contact_forces": np.zeros((len(log), 3, 6))}))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s.target(log.with_(extras={**log.extras, "contact_forces": np.zeros((len(log), 2, 6))}))
    assert any("all zero" in str(w.message) for w in caught)


def test_cli_identify_from_urdf_without_torques(tmp_path, solo12):
    """End to end on a quadruped URDF (loaded floating automatically since contact frames are
    given), point feet, no torques, per-foot world bias; result.json carries the identified
    mass/CoM and the floating-base checks; predict reloads the bias columns."""
    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    truth = perturbed_truth(solo12, rng=5)
    bias = np.array([[2.0, -1.0, 0], [0, 0, 0], [-1.5, 0, 0], [0, 0, 0]])
    lg = wrench_log(truth.robot, feet, duration=4.0, bias=bias, bias_frame="world", dims=3, seed=3,
                    base_amplitude=(0.2, 0.4))
    path = write_npz(lg, tmp_path / "trot.npz")
    out = tmp_path / "out"
    args = ["identify", "--robot", solo12.urdf_path, "--data", str(path), "--out", str(out), "--contact-frames",
            ",".join(feet), "--contact-mode", "wrench", "--wrench-offset", "foot", "--joint-terms", "", "--method", "ols"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "contact rows: base" in res.output
    doc = json.loads((out / "result.json").read_text())
    assert doc["robot"]["floating_base"] and doc["settings"]["contact_rows"] == "base"
    assert doc["floating_base"]["wrench_offset"]["FL_FOOT"]["fx"] == pytest.approx(2.0, abs=1e-3)
    assert doc["floating_base"]["train"][0]["com_cop"]["ok"] is True
    assert doc["floating_base"]["train"][0]["base_wrench"]["force_rmse_norm"] < 1e-3
    m_true = float(truth.robot.inertial_parameters().reshape(-1, 10)[:, 0].sum())
    assert doc["mass_properties"]["total_mass"] == pytest.approx(m_true, rel=1e-6)
    pred = CliRunner().invoke(app, ["predict", "--robot", solo12.urdf_path, "--floating-base", "--model", str(out),
                                    "--data", str(path), "--out", str(tmp_path / "p.npz")])
    assert pred.exit_code == 0, pred.output
    # an explicit --fixed-base gets the error that names the option
    bad = CliRunner().invoke(app, args[:-2] + ["--fixed-base", "--out", str(tmp_path / "o2")])
    assert bad.exit_code != 0 and "--floating-base" in bad.output


def test_cli_imu_frame_option(tmp_path, solo12):
    """--imu-frame: base_a rebuilt from 'imu_acc' read in a model frame; a log without
    'imu_acc' is a clear error."""
    from sensorless.data.imu import gravity_in_base

    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    truth = perturbed_truth(solo12, rng=6)
    lg = wrench_log(truth.robot, feet, duration=3.0, dims=3, seed=4, base_amplitude=(0.2, 0.4))
    v, w = lg.base_v[:, :3], lg.base_v[:, 3:]
    imu = lg.base_a[:, :3] + np.cross(w, v) - gravity_in_base(lg.base_q, 9.81)  # accelerometer at base_link
    m_true = float(truth.robot.inertial_parameters().reshape(-1, 10)[:, 0].sum())
    path = write_npz(lg.with_(base_a=None, extras={**lg.extras, "imu_acc": imu}), tmp_path / "imu.npz")
    base = ["identify", "--robot", "solo12", "--data", str(path), "--contact-frames", ",".join(feet),
            "--contact-mode", "wrench", "--joint-terms", ""]
    res = CliRunner().invoke(app, base + ["--imu-frame", "base_link", "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "a" / "result.json").read_text())
    assert doc["mass_properties"]["total_mass"] == pytest.approx(m_true, rel=2e-3)
    bad = CliRunner().invoke(app, base + ["--imu-frame", "no_such_imu", "--out", str(tmp_path / "b")])
    assert bad.exit_code != 0 and "no frame 'no_such_imu'" in bad.output and not (tmp_path / "b").exists()


def test_wrench_log_warns_when_the_contacts_cannot_balance_the_base(solo12):
    """Point feet: two or one in contact cannot produce an arbitrary base wrench; the generator
    says so instead of writing an inconsistent log silently (all four down: no warning)."""
    import warnings

    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    n = 100
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wrench_log(solo12, feet, duration=1.0, dims=3, seed=1)
    flags = np.ones((n, 4), bool)
    flags[50:] = [True, False, False, False]
    with pytest.warns(RuntimeWarning, match="cannot produce the base wrench"):
        wrench_log(solo12, feet, duration=1.0, dims=3, seed=1, flags=flags)

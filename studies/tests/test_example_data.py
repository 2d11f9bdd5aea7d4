"""`sensorless example NAME --out DIR` for docs/surgical-arm.md: the files the doc uses exist, and the
simulated logs are consistent with the ground truth written beside them (the documented chain
identify → estimate-force / payload recovers it)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import read_trajectory
from sensorless.estimation import CartesianForceEstimator
from sensorless.torque_models import PhysicalModel
from sensorless.identification import identify, identify_payload
from sensorless.robot import load_robot
from sensorless.robots import psm_structure, read_psm_log


def _example(name: str, out, *extra: str) -> str:
    r = CliRunner().invoke(app, ["example", name, "--out", str(out), *extra])
    assert r.exit_code == 0, r.output
    return r.output


def test_example_list_names_the_surgical_examples():
    out = CliRunner().invoke(app, ["example", "--list"]).output
    assert "dvrk-psm" in out and "trocar-arm" in out


@pytest.fixture(scope="module")
def psm_data(tmp_path_factory):
    d = tmp_path_factory.mktemp("ex") / "psm_data"
    _example("dvrk-psm", d)
    return d


def test_dvrk_psm_example_logs_are_wpi_format_and_recover_their_truth(psm_data):
    d = psm_data
    truth = json.loads((d / "truth.json").read_text())
    for name in ("free", "palpation", "loaded", "unloaded"):
        raw = np.loadtxt(d / f"{name}.csv", delimiter=",")
        assert raw.shape[1] == 21 and np.isfinite(raw).all()  # header-less q, q̇, effort of 7 coordinates
    free, palp = (read_psm_log(d / f"{n}.csv", cutoff_hz=5.4) for n in ("free", "palpation"))
    s = psm_structure(coulomb_smoothing=truth["coulomb_smoothing"])
    result = identify(s, free)
    assert np.all(result.score(free).nrmse < 0.02)
    # the palpation's efforts carry exactly the documented tip force
    est = CartesianForceEstimator(s.robot, "tool_tip", "local_world_aligned", components="linear")
    res = est.estimate(palp, PhysicalModel.from_parameters(s, result.parameters))
    F = np.loadtxt(d / "palpation_force.csv", delimiter=",", skiprows=1)
    assert F.shape == (len(palp), 4) and np.abs(F[:, 3]).max() > 0.5  # presses, mostly down
    err = np.sqrt(((res.F - F[:, 1:]) ** 2)[50:-50].mean(axis=0))  # ends: filter edge effects
    assert np.all(err < 0.1 * np.sqrt((F[:, 1:] ** 2).mean(axis=0)).max()), err
    # the payload pair holds the payload of truth.json
    loaded, unloaded = (read_psm_log(d / f"{n}.csv", cutoff_hz=5.4) for n in ("loaded", "unloaded"))
    pay = identify_payload(result, loaded, truth["payload"]["frame"], no_load=unloaded, offsets="auto", n_boot=20)
    assert pay.mass == pytest.approx(truth["payload"]["mass_kg"], rel=0.02)
    assert np.allclose(pay.com, truth["payload"]["com_m"], atol=0.02)


def test_trocar_arm_example_urdf_keeps_the_tool_frame_and_logs_carry_the_force(tmp_path, monkeypatch):
    from sensorless_studies.example_data import trocar_arm
    from sensorless_studies.simulation.surgical_arm import build_surgical_arm

    monkeypatch.setattr(trocar_arm, "QUICK", dict.fromkeys(trocar_arm.QUICK, 1.0))  # 1 s logs: the layout only
    _example("trocar-arm", tmp_path / "t")
    d = tmp_path / "t"
    robot, nominal = load_robot(d / "psm_like.urdf"), build_surgical_arm()
    assert robot.joint_names == nominal.joint_names and robot.frame_id("tool_tip") is not None
    for name in ("free", "port_1", "port_2", "port_test", "contact"):
        log = read_trajectory(d / f"{name}.npz", robot=robot)
        assert log.tau is not None and len(log) == 200  # 1 s at 200 Hz
    F = np.loadtxt(d / "contact_force.csv", delimiter=",", skiprows=1)
    assert F.shape == (200, 4) and np.isfinite(F).all()

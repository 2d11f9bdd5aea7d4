"""Issue 39 item 2: one set of numbers. model.urdf, result.json, the console and report.html show the same
presented model, each value with its verdict; `prior` means the value written is the prior's; on logs that
move one joint at a time the written masses stay within ×/÷ 2 of the prior."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless import load_robot
from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.data.trajectory import Trajectory
from sensorless.identification import identify
from sensorless.parameters import check_physical_consistency
from sensorless.report.html_format import num
from sensorless.testing import (RealArtefacts, one_joint_at_a_time, perturbed_truth, synthetic_trajectory,
                                with_real_artefacts)

ARTEFACTS = RealArtefacts(q_step=1e-4, decimals=4)  # a UR's encoders and its 4-decimal log


def _single_joint_log(robot, seed: int, amplitude: float = 0.6):
    truth = perturbed_truth(robot, rng=seed)
    t = np.arange(0, 36, 0.005)
    q0 = np.random.default_rng(seed).uniform(-1.0, 1.0, len(robot.joint_names))
    q, v, a = one_joint_at_a_time(t, q0, amplitude=amplitude, period=3.0)
    log = synthetic_trajectory(truth, Trajectory(t=t, q=q, v=v, a=a, joint_names=robot.joint_names, source="<1j>"),
                               noise_std=0.05, rng=seed)
    return with_real_artefacts(log, ARTEFACTS, rng=seed)


@pytest.mark.parametrize("seed", [0, 1])
def test_single_joint_logs_write_masses_near_the_prior_and_every_output_agrees(ur5, tmp_path, seed):
    log = _single_joint_log(ur5, seed)
    write_npz(log, tmp_path / "log.npz")
    out = tmp_path / "m"
    r = CliRunner(env={"COLUMNS": "200"}).invoke(app, ["identify", "--robot", "ur5", "--data", str(tmp_path / "log.npz"), "--out", str(out),
                                 "--no-plot", "--savgol-window", "31"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "result.json").read_text())
    v = doc["diagnostics"]["verdicts"]
    urdf = load_robot(out / "model.urdf").inertial_parameters().reshape(-1, 10)
    page = (out / "report.html").read_text()
    m0 = ur5.inertial_parameters().reshape(-1, 10)[:, 0]
    assert all(rep.consistent for rep in check_physical_consistency(urdf.ravel()))
    for k, b in enumerate(ur5.body_names):
        m = doc["parameters"][f"{b}.m"]
        assert urdf[k, 0] == pytest.approx(m, rel=1e-9)  # model.urdf = result.json's parameters
        for ax, q in enumerate("xyz"):
            assert urdf[k, 1 + ax] == pytest.approx(doc["parameters"][f"{b}.m{q}"], rel=1e-9, abs=1e-12)
        e = v["bodies"][b]["mass"]
        assert e["value"] == pytest.approx(m, rel=1e-12)  # = the verdicts' values (what report.html shows)
        assert 0.5 < urdf[k, 0] / m0[k] < 2.0, (b, urdf[k, 0], m0[k])
        if e["verdict"] == "prior":
            assert urdf[k, 0] == pytest.approx(m0[k], rel=1e-9)  # `prior`: the value written is the prior's
        if e["verdict"] != "undetermined":
            assert re.search(rf"<td class=val>{re.escape(num(m))}</td>", page)  # report.html
    for j, terms in v["joints"].items():  # every interval holds its value
        for t, e in terms.items():
            if e["interval"] is not None:
                assert e["interval"][0] <= e["value"] <= e["interval"][1]


def test_prior_verdict_means_the_prior_value_in_the_library(ur5):
    """identify() directly: the presented model keeps the fit in diagnostics, predicts the training torques
    almost as well as the fit (it only spends s²κ of residual), and every `prior` entry holds the prior's value."""
    log = _single_joint_log(ur5, 3)
    from sensorless.data.prepare import prepare

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify(ur5, prepare(log, savgol_window=31), method="lmi", gamma=1e-3)
    shown = res.diagnostics["presented"]
    assert "fit_parameters" in shown and shown["rss"] <= shown["rss_budget"] * (1 + 1e-6)
    fit = np.array(shown["fit_parameters"])
    ne = res.equations
    rss_fit, rss = ne.residual_ss(fit).sum(), ne.residual_ss(res.parameters).sum()
    assert rss <= 1.02 * rss_fit, (rss, rss_fit)
    for b, entries in res.diagnostics["verdicts"]["bodies"].items():
        for q, e in entries.items():
            if e["verdict"] == "prior":
                assert e["value"] == pytest.approx(e["prior"], rel=1e-4, abs=1e-6), (b, q)

"""docs/arm.md §6 runs as written: the current-logged arm example (issue 11, Deliver 4).

The fenced block that starts with ``sensorless example current-arm`` is executed line by line
through the CLI in a temporary directory (tests/test_docs_run.py runs it as a shell would). The
identified model's held-out error must be close to the error of the true model on the same
preprocessed log.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import prepare, read_trajectory
from sensorless.identification.metrics import torque_metrics
from sensorless_studies.simulation.current_arm import truth_model

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "arm.md"


def _documented_commands() -> list[list[str]]:
    text = DOC.read_text()
    m = re.search(r"```bash\n(sensorless example current-arm .*?)```", text, re.S)
    assert m, "docs/arm.md lost its current-arm example block"
    lines = m.group(1).replace("\\\n", " ").splitlines()
    return [shlex.split(line, comments=True) for line in lines if line.strip()]


def test_documented_current_example_runs_and_matches_the_truth_model(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cmds = _documented_commands()
    assert [c[:2] for c in cmds] == [["sensorless", "example"], ["sensorless", "identify"], ["sensorless", "predict"]]
    for cmd in cmds:
        r = CliRunner().invoke(app, cmd[1:])
        assert r.exit_code == 0, f"{' '.join(cmd)}\n{r.output}"

    out = tmp_path / "current_demo"
    doc = json.loads((tmp_path / "current_model" / "result.json").read_text())
    assert doc["settings"]["preprocessing"]["gains"] == json.loads((out / "gains.json").read_text())
    sig = doc["settings"]["signals"][str(Path("current_demo/train.csv"))]
    assert sig["v"] == "logged" and sig["a"].startswith("derived: d/dt of logged v")
    assert 1 <= sig["resampled"]["duplicates_merged"] <= 3 and sig["timing"]["jitter"] > 0.1
    held = doc["validation"][str(Path("current_demo/test.csv"))][doc["method"]]["per_joint"]

    # the true model on the same log, preprocessed the same way
    robot, truth = truth_model("ur5", 0)
    prep = doc["settings"]["preprocessing"]
    te = read_trajectory(out / "test.csv", columns=prep["columns"], gains=prep["gains"], robot=robot,
                         allow_duplicate_times=True)
    te = prepare(te, trim=prep["trim"], resample=prep["resample"], savgol_window=prep["savgol_window"])
    tau_true = truth.torques(robot.full_configuration(te.q), robot.full_velocity(te.v), robot.full_velocity(te.a))
    ref = torque_metrics(te.tau, tau_true, list(robot.joint_names))
    ident = np.array([held[j]["nrmse"] for j in robot.joint_names])
    ratio = ident / ref.nrmse
    assert ratio.mean() < 1.1 and ratio.max() < 1.25, dict(zip(robot.joint_names, ratio.round(3)))
    cad = doc["validation"][str(Path("current_demo/test.csv"))]["cad"]["mean_nrmse"]
    assert ident.mean() < 0.25 * cad  # the CAD model is far off; the identified one is not

    z = np.load(tmp_path / "current_pred.npz")  # predict used the model's column map and gains
    rel = np.sqrt(np.mean((z["tau_pred"] - z["tau_measured"]) ** 2, 0)) / np.ptp(z["tau_measured"], 0)
    np.testing.assert_allclose(rel, ident, rtol=1e-6)

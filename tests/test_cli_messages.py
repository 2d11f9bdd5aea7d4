"""Messages of the first day (issue 42): every printed force has its unit, and a log of motor currents
without --gains says to give --gains."""

from __future__ import annotations

import re

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("messages")
    ur5 = load_robot("ur5")
    log = synthetic_trajectory(perturbed_truth(ur5, rng=0), random_fourier(ur5, rng=1).sample(100.0, 6.0),
                               noise_std=0.1, rng=2)
    write_npz(log, d / "log.npz")
    header = ",".join(["t"] + [f"pos_{j}" for j in ur5.joint_names] + [f"vel_{j}" for j in ur5.joint_names]
                      + [f"i_{j}" for j in ur5.joint_names])
    np.savetxt(d / "cur.csv", np.column_stack([log.t, log.q, log.v, log.tau / 10.0]), delimiter=",", header=header,
               comments="")
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "log.npz"), "--method", "ols",
                                 "--no-plot", "--out", str(d / "m")])
    assert r.exit_code == 0, r.output
    return d


def test_estimate_force_prints_each_component_with_its_unit(folder, tmp_path):
    r = CliRunner().invoke(app, ["estimate-force", "--robot", "ur5", "--model", str(folder / "m"), "--data",
                                 str(folder / "log.npz"), "--frame", "tool0", "--components", "wrench",
                                 "--out", str(tmp_path / "f.npz"), "--no-plot"])
    text = " ".join(r.output.split())
    assert r.exit_code == 0, r.output
    rms = re.search(r"RMS (.*?); damped", text).group(1)
    parts = dict(p.split("=") for p in rms.split(", "))
    assert set(parts) == {"fx", "fy", "fz", "mx", "my", "mz"}, rms
    assert all(parts[k].endswith(" N") for k in ("fx", "fy", "fz")) and all(parts[k].endswith(" N·m") for k in ("mx", "my", "mz"))


def test_currents_without_gains_name_the_gains_option(folder):
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(folder / "cur.csv"), "--no-plot",
                                 "--out", str(folder / "x")])
    text = " ".join(r.output.split())
    assert r.exit_code == 2 and "motor currents" in text and "--gains FILE" in text and "'tau'" not in text, text

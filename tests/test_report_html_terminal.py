"""report.html says what the terminal said (issue 42): every warning printed during the run, cells
without a data interval as "—" with their verdict (never "∞"), and base parameters the data do not
determine counted by the verdicts' rule, so that "0 poorly identified" never sits above a relative
standard deviation of millions of percent unexplained."""

from __future__ import annotations

import json
import re

from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.excitation import random_fourier
from sensorless.identification.verdicts import DATA_REL_STD
from sensorless.robot import load_robot
from sensorless.testing import perturbed_truth, synthetic_trajectory


def test_the_report_holds_the_terminals_warnings_and_no_infinity(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ur5 = load_robot("ur5")
    log = synthetic_trajectory(perturbed_truth(ur5, rng=0), random_fourier(ur5, rng=1).sample(100.0, 5.0),
                               noise_std=0.1, rng=2)
    write_npz(log, "log.npz")
    import numpy as np

    z = dict(np.load("log.npz"))
    z["motor_temp"] = np.full_like(z["positions"], 40.0)  # an array no field uses: a printed warning
    np.savez("log2.npz", **z)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", "log2.npz", "--gamma", "1e-3", "--out", "m"])
    assert r.exit_code == 0, r.output
    printed = [" ".join(line.split()) for line in r.output.split("warning:")[1:]]
    assert any("motor_temp" in p for p in printed), r.output
    page = (tmp_path / "m" / "report.html").read_text()
    assert "motor_temp" in page
    assert "∞" not in page
    doc = json.loads((tmp_path / "m" / "result.json").read_text())
    rel = doc["diagnostics"]["base_relative_std"]
    undetermined = sum(1 for x in rel if x is None or x > DATA_REL_STD)
    m = re.search(r"<b>(\d+)</b> of (\d+) base parameter\(s\) not determined by the data", page)
    assert m and int(m.group(1)) == undetermined and int(m.group(2)) == len(rel), page[:2000]
    assert undetermined > 0  # 5 s of a UR5: some directions rest on the prior
    assert len(doc["diagnostics"]["poorly_identified"]) <= undetermined


def test_library_setting_names_never_reach_the_command_line_user(tmp_path, monkeypatch):
    """Hints name the command's flags, not Python fields: the `say` lines of identify go through the
    same translation as its warnings (issue 42: `execution.scheduler`, `joint_terms` in hints)."""
    from sensorless.cli.flags import cli_words
    from sensorless.errors import setting

    line = f"{setting('execution.scheduler')}: Coulomb smoothing from x; drop them ({setting('joint_terms')})"

    import typer

    from sensorless.cli import app

    cmd = typer.main.get_command(app).get_command(typer.Context(typer.main.get_command(app)), "identify")
    ctx = typer.Context(cmd)
    with ctx:
        words = cli_words(line)
    assert "--scheduler" in words and "--joint-terms" in words and "`" not in words, words

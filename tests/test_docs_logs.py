"""docs/logs.md runs as printed: its Python block makes the logs, then every `sensorless`
command of its bash blocks exits 0 (and the tick column is refused without its flags, as it says)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from typer.testing import CliRunner

DOC = Path(__file__).resolve().parents[1] / "docs" / "logs.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def _commands() -> list[list[str]]:
    out = []
    for block in _blocks("bash"):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip().startswith("sensorless "):
                out.append(shlex.split(line)[1:])
    return out


def test_logs_doc_runs_as_printed(tmp_path, monkeypatch):
    from sensorless.cli import app

    monkeypatch.chdir(tmp_path)
    (python,) = _blocks("python")
    exec(compile(python, str(DOC), "exec"), {})
    # the commands on the logs the Python block makes (the long-log section has its own data step,
    # run by tests/test_docs_run.py)
    commands = [c for c in _commands() if any(a.startswith("lab_logs/") for a in c)]
    assert len(commands) == 7
    run = CliRunner().invoke
    for args in commands:
        r = run(app, args)
        assert r.exit_code == 0, (args, r.output)
        if "run.npz" in args:
            assert "arrays not used: 'motor_temp'" in " ".join(r.output.split())
    r = run(app, ["identify", "--robot", "ur5", "--data", "lab_logs/run", "--method", "ols", "--out", "lab_refused"])
    text = " ".join(r.output.split())
    assert r.exit_code == 2 and "time column 'tick' counts controller ticks" in text and "--time-unit tick --rate HZ" in text


def test_readme_links_the_logs_doc():
    assert "(docs/logs.md)" in (DOC.parents[1] / "README.md").read_text(encoding="utf-8")

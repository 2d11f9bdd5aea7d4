"""CLI outputs (issue 12): `--force` never deletes what sensorless did not write, an existing
OUT is untouched without it, failures are one-line typed errors (exit 2) that leave nothing
behind, result.json is strict JSON, and SIGTERM leaves no hidden temporary directory.

Every refusal test runs in a temporary directory and checks that a canary file survives.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.io import atomic_output_dir
from sensorless.outdir import MANIFEST, read_manifest

runner = CliRunner()
ROBOT = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def log(panda_train_npz):
    return panda_train_npz


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _canary(d: Path, name: str = "canary.txt") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    f = d / name
    f.write_text("alive")
    return f


def _one_line_error(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output)
    text = r.output.strip()
    assert text.startswith("error:") and "Traceback" not in text, text
    assert text.count("\n") <= 2, text  # one message (rich may wrap long lines)
    for n in needles:
        assert n in text.replace("\n", ""), text


def _copy_log(log: Path, d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    dst = d / "train.npz"
    dst.write_bytes(log.read_bytes())
    return dst


def _identify(data, out, *extra):
    return _run("identify", *ROBOT, "--data", data, "--out", out, *extra)


def test_force_out_dot_keeps_the_working_directory(log, tmp_path, monkeypatch):
    data = _copy_log(log, tmp_path)
    canary = _canary(tmp_path)
    monkeypatch.chdir(tmp_path)
    r = _identify("train.npz", ".", "--force")
    _one_line_error(r, "'.'")
    assert canary.read_text() == "alive" and data.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["canary.txt", "train.npz"]


def test_force_out_dotdot_keeps_the_parent_tree(log, tmp_path, monkeypatch):
    work = tmp_path / "work"
    data = _copy_log(log, work)
    canaries = [_canary(tmp_path), _canary(work)]
    monkeypatch.chdir(work)
    r = _identify(data, "..", "--force")
    _one_line_error(r, "..")
    assert all(c.exists() for c in canaries) and data.exists()


def test_force_out_home_keeps_home(log, tmp_path, monkeypatch):
    home = tmp_path / "home"
    canary = _canary(home)
    monkeypatch.setenv("HOME", str(home))
    r = _identify(log, home, "--force")
    _one_line_error(r, str(home), "home directory")
    assert canary.exists() and sorted(p.name for p in home.iterdir()) == ["canary.txt"]


def test_force_out_working_directory_by_absolute_path(log, tmp_path, monkeypatch):
    canary = _canary(tmp_path)
    monkeypatch.chdir(tmp_path)
    r = _identify(log, tmp_path, "--force")
    _one_line_error(r, str(tmp_path), "working directory")
    assert canary.exists()


def test_force_out_foreign_directory_is_refused(log, tmp_path):
    out = tmp_path / "photos"
    canary = _canary(out)
    r = _identify(log, out, "--force")
    _one_line_error(r, str(out), "did not create")
    assert canary.exists() and sorted(p.name for p in out.iterdir()) == ["canary.txt"]


def test_force_out_directory_holding_the_input_is_refused(log, tmp_path):
    logs = tmp_path / "logs"
    data = _copy_log(log, logs)
    canary = _canary(logs)
    r = _identify(data, logs, "--force")
    _one_line_error(r, str(logs))
    assert canary.exists() and data.exists()
    # even when the folder is a previous sensorless output (e.g. `demo_output/train.npz`)
    prev = tmp_path / "prev"
    assert _identify(data, prev).exit_code == 0
    inside = _copy_log(log, tmp_path / "elsewhere")
    (prev / "train.npz").write_bytes(inside.read_bytes())
    man = read_manifest(prev)
    man["files"].append("train.npz")
    (prev / MANIFEST).write_text(json.dumps(man))
    r = _identify(prev / "train.npz", prev, "--force")
    _one_line_error(r, "input")
    assert (prev / "train.npz").exists() and (prev / "result.json").exists()


def test_previous_output_is_replaced_with_force_and_kept_without(log, tmp_path):
    out = tmp_path / "run"
    r = _identify(log, out)
    assert r.exit_code == 0, r.output
    man = read_manifest(out)
    assert man["command"]["name"] == "sensorless identify"
    assert {"result.json", "joint_terms.json", "torques.png"} <= set(man["files"])
    assert set(man["files"]) == {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()} - {MANIFEST}
    stamp = (out / "result.json").stat().st_mtime_ns
    r = _identify(log, out)
    _one_line_error(r, "--force")
    assert (out / "result.json").stat().st_mtime_ns == stamp
    (out / "stale.txt").write_text("written by the user")  # refused: not written by sensorless
    _one_line_error(_identify(log, out, "--force"), "stale.txt")
    (out / "stale.txt").unlink()
    time.sleep(0.01)
    r = _identify(log, out, "--force")
    assert r.exit_code == 0, r.output
    assert (out / "result.json").stat().st_mtime_ns != stamp
    assert not list(tmp_path.glob(".run.*"))


@pytest.fixture(scope="module")
def ran(log, tmp_path_factory):
    """One successful `identify` under umask 022."""
    out = tmp_path_factory.mktemp("ran") / "run"
    old = os.umask(0o022)
    try:
        r = _identify(log, out)
    finally:
        os.umask(old)
    assert r.exit_code == 0, r.output
    return out


def test_result_json_is_strict_json(ran):
    def no_constants(name):
        raise AssertionError(f"bare {name} in result.json")

    doc = json.loads((ran / "result.json").read_text(), parse_constant=no_constants)
    assert np.isfinite(doc["diagnostics"]["condition_number"])
    json.loads((ran / MANIFEST).read_text(), parse_constant=no_constants)


def test_output_permissions_follow_umask(ran):
    assert ran.stat().st_mode & 0o777 == 0o755
    for f in ran.iterdir():
        assert f.stat().st_mode & 0o777 == 0o644, f


def test_unwritable_out_is_exit_2_not_internal_error(log, tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    r = _identify(log, blocker / "out")
    _one_line_error(r, str(blocker))
    assert blocker.read_text() == "x"


def test_concurrent_run_on_the_same_out_fails_clearly(log, tmp_path):
    out = tmp_path / "run"
    assert _identify(log, out).exit_code == 0
    inside, release = threading.Event(), threading.Event()

    def other_run():  # another sensorless process writing the same OUT
        with atomic_output_dir(out, force=True) as tmp:
            (tmp / "result.json").write_text("{}")
            inside.set()
            release.wait(30)

    t = threading.Thread(target=other_run)
    t.start()
    try:
        assert inside.wait(10)
        r = _identify(log, out, "--force")
        _one_line_error(r, str(out), "another sensorless run")
    finally:
        release.set()
        t.join(10)
    assert (out / "result.json").read_text() == "{}"  # the run that reported success is the one on disk


def test_predict_out_directory_is_a_clear_error_without_stray_files(log, ran, tmp_path):
    model = ran
    d = tmp_path / "preds"
    canary = _canary(d)
    r = _run("predict", *ROBOT, "--model", model, "--data", log, "--out", d)
    _one_line_error(r, str(d), "directory")
    assert sorted(p.name for p in d.iterdir()) == ["canary.txt"] and canary.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["preds"] and not list(ran.parent.glob(".*"))
    # never over the input log
    data = _copy_log(log, tmp_path / "in")
    before = data.read_bytes()
    r = _run("predict", *ROBOT, "--model", model, "--data", data, "--out", data)
    _one_line_error(r, "input")
    assert data.read_bytes() == before
    r = _run("predict", *ROBOT, "--model", model, "--data", log, "--out", d / "p.npz")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in d.iterdir()) == ["canary.txt", "p.html", "p.npz", "p.png"]  # the fit drawn beside it


def test_estimate_force_out_directory_is_a_clear_error(log, tmp_path):
    d = tmp_path / "forces"
    canary = _canary(d)
    r = _run("estimate-force", *ROBOT, "--model", tmp_path / "nope", "--data", log, "--frame", "panda_hand", "--out", d)
    _one_line_error(r, str(d), "directory")
    assert canary.exists() and sorted(p.name for p in d.iterdir()) == ["canary.txt"]


@pytest.mark.parametrize("cmd", [
    ["demo"],
    ["excite", "--robot", "ur5", "--force"],
    ["experiment", "torque-control", "--quick", "--force"],
    ["experiment", "hybrid-force", "--quick", "--force"],
    ["experiment", "contact-id", "--quick", "--force"],
    ["experiment", "psm-identify", "--data", "/nonexistent", "--force"],
])
def test_every_output_command_refuses_a_foreign_directory(tmp_path, cmd):
    out = tmp_path / "mine"
    canary = _canary(out)
    r = _run(*cmd, "--out", out)
    _one_line_error(r, str(out))
    assert canary.exists() and sorted(p.name for p in out.iterdir()) == ["canary.txt"]
    assert not list(tmp_path.glob(".mine.*"))


def test_sigterm_during_demo_leaves_no_hidden_directory(tmp_path):
    """A real CLI run (the demo) killed with SIGTERM mid-way: no output, no temporary directory."""
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    p = subprocess.Popen([sys.executable, "-c", "from sensorless.cli import app; app()", "demo", "--out", "demo_output"],
                         cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(".demo_output.tmp-*")):
            assert p.poll() is None and time.monotonic() < deadline, "the demo never started writing"
            time.sleep(0.05)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 128 + signal.SIGTERM, err
    assert sorted(x.name for x in tmp_path.iterdir()) == [], list(tmp_path.iterdir())

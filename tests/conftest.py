"""Shared fixtures: robots, synthetic logs, and the real-data folder (skip when absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorless.robot import load_robot

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
KUKA = REALDATA / "kuka_lwr4_flobaroid"
PANDA_LOCK = ["panda_finger_joint1", "panda_finger_joint2"]


def identify_imports(robot, tmp_path: Path, args: list[str], modules: list[str]) -> tuple[Path, dict[str, bool]]:
    """``sensorless identify --robot ur5 --data LOG *args --no-plot`` on a small simulated UR5 log, in a
    fresh Python: the output folder and, at the exit, whether each of ``modules`` was imported."""
    import json
    import subprocess
    import sys

    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    log = synthetic_trajectory(perturbed_truth(robot, rng=0), random_fourier(robot, rng=1).sample(300, 6.0),
                               noise_std=0.1, rng=2)
    f = write_npz(log, tmp_path / "log.npz")
    out = tmp_path / "out"
    argv = ["sensorless", "identify", "--robot", "ur5", "--data", str(f), *args, "--no-plot", "--out", str(out)]
    code = ("import atexit, json, sys; from sensorless.cli import app; "
            f"atexit.register(lambda: print('IMPORTED', json.dumps({{m: m in sys.modules for m in {modules!r}}}))); "
            f"sys.argv = {argv!r}; app()")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:] + r.stdout[-3000:]
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("IMPORTED ")]
    assert line, r.stdout[-2000:]
    return out, json.loads(line[-1][len("IMPORTED "):])


def realdata(path: Path) -> Path:
    """Return ``path`` or skip the test cleanly when the shared real data is absent."""
    if not path.exists():
        pytest.skip(f"real data not available: {path}")
    return path


@pytest.fixture(scope="session")
def panda():
    return load_robot("panda", lock_joints=PANDA_LOCK)


@pytest.fixture(scope="session")
def ur5():
    return load_robot("ur5")


@pytest.fixture(scope="session")
def solo12():
    return load_robot("solo12")


@pytest.fixture(scope="session")
def kuka():
    return load_robot(realdata(KUKA / "model" / "kuka_lwr4.urdf"))


@pytest.fixture(autouse=True)
def _seed_pinocchio():
    """Pinocchio's own generator (Inertia.Random, SE3.Random, randomConfiguration) seeded per test,
    so that no test depends on which tests ran before it in the same worker."""
    import pinocchio as pin

    pin.seed(1234)


@pytest.fixture(scope="session")
def panda_train_npz(tmp_path_factory, panda):
    """A 10 s simulated Panda log (50 Hz, σ_τ = 0.1 N·m) as NPZ, shared by the output-safety tests."""
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    d = tmp_path_factory.mktemp("panda_log")
    truth = perturbed_truth(panda, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(50, 10.0), noise_std=0.1, rng=2)
    return write_npz(tr, d / "train.npz")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def pytest_configure(config):
    """The doc-block log (tests/test_docs_run.py) is shared by the xdist workers through the environment."""
    import os
    import tempfile

    if not hasattr(config, "workerinput") and "SENSORLESS_DOC_LOG" not in os.environ:
        fd, path = tempfile.mkstemp(prefix="sensorless-doc-blocks-", suffix=".jsonl")
        os.close(fd)
        os.environ["SENSORLESS_DOC_LOG"] = path
        config._sensorless_doc_log = path


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """List every doc block the session ran (file:line, language, status, seconds)."""
    import json
    import os

    path = getattr(config, "_sensorless_doc_log", None)
    if not path or not os.path.exists(path):
        return
    with open(path, encoding="utf-8") as fh:
        entries = [json.loads(line) for line in fh if line.strip()]
    os.unlink(path)
    if not entries:
        return
    ran = [e for e in entries if e["status"] != "skipped"]
    terminalreporter.section(f"doc blocks: {len(ran)} run, {len(entries) - len(ran)} skipped")
    for e in sorted(entries, key=lambda e: e["block"]):
        extra = f"{e.get('seconds', 0):7.1f} s" if e["status"] != "skipped" else e.get("reason", "")
        terminalreporter.write_line(f"{e['status']:8} {e['lang']:6} {e['block']:40} {extra}")
    out = "/tmp/sensorless-bench/doc_blocks.json"
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, "w", encoding="utf-8") as fh:
        json.dump({"run": len(ran), "skipped": len(entries) - len(ran), "blocks": entries}, fh, indent=1)

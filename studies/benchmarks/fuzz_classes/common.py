"""Shared pieces of the fuzz classes: outcome names, CLI runs, planted secrets and markers, snapshots.

Outcomes (``OUTCOMES``): the six of issue 12 (``typed`` ``ok`` ``generic`` ``garbage`` ``hang``
``crash``) plus three of issue 26:

* ``data_loss``  — after the case the previous output is neither intact nor replaced by a complete
  new one (complete: the ``.sensorless-output.json`` manifest and every file it lists), or an input
  or user file changed, or a special file (FIFO, device) was replaced by a regular file;
* ``executed``   — a marker file a hostile payload writes exists afterwards (critical);
* ``disclosure`` — a secret planted in a temporary file shows up in an output or an error text.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import stat
from pathlib import Path

OUTCOMES = ("typed", "ok", "generic", "garbage", "hang", "crash", "data_loss", "executed", "disclosure")
BAD = ("generic", "garbage", "hang", "crash", "data_loss", "executed", "disclosure")
TWO_LINK = (Path(__file__).resolve().parents[3] / "tests" / "data" / "two_link.urdf").read_text()
MANIFEST = ".sensorless-output.json"


class Hang(BaseException):
    """Raised by SIGALRM; a BaseException so that ``except Exception`` in the code under test lets it through."""


def one_line(text: str, n: int = 200) -> str:
    return " ".join(str(text).split())[:n]


# ---- planted secret and marker -------------------------------------------------------------------
def plant_secret(d: Path) -> tuple[Path, str]:
    """A file whose first line is a unique secret (a stand-in for /etc/shadow); returns (path, secret)."""
    s = "SENSORLESS-SECRET-" + secrets.token_hex(8)
    f = d / "secret.txt"
    f.write_text(f"{s}:x:0:0:root:/root:/bin/sh\nsecond line {s}\n")
    return f, s


def leaked(secret: str, *texts, files=()) -> bool:
    """``secret`` in any of ``texts`` or in any of ``files`` (bytes, recursive for folders)."""
    if any(secret in str(t) for t in texts if t is not None):
        return True
    b = secret.encode()
    for f in files:
        f = Path(f)
        paths = [p for p in f.rglob("*") if p.is_file() and not p.is_symlink()] if f.is_dir() else [f]
        for p in paths:
            try:
                if p.is_file() and b in p.read_bytes():
                    return True
            except OSError:
                pass
    return False


# ---- CLI ----------------------------------------------------------------------------------------
def cli(args: list[str]):
    """Run ``sensorless ARGS`` in-process (typer's CliRunner); a Hang propagates."""
    from typer.testing import CliRunner

    from sensorless.cli import app

    r = CliRunner().invoke(app, [str(a) for a in args])
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        if isinstance(r.exception, Hang):
            raise r.exception
    return r


def cli_outcome(r, what: str) -> tuple[str | None, str]:
    """("typed"|"generic", message) for a failed run; (None, "") when it exited 0."""
    text = r.output
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        return "generic", f"{what}: uncaught {type(r.exception).__name__}: {one_line(r.exception)}"
    if "internal error" in text or "Traceback" in text or r.exit_code not in (0, 1, 2):
        return "generic", f"{what}: exit {r.exit_code}: {one_line(text)}"
    if r.exit_code == 0:
        return None, ""
    return "typed", ""


def warned(text: str) -> bool:
    return "warning" in text.lower()


# ---- snapshots ----------------------------------------------------------------------------------
def digest(path: Path) -> str:
    """A fingerprint of what ``path`` is: file type, and content for files and folders (lstat, no follow)."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return "missing"
    if stat.S_ISLNK(st.st_mode):
        return "link:" + os.readlink(path)
    if stat.S_ISFIFO(st.st_mode):
        return "fifo"
    if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode):
        return f"dev:{st.st_rdev}"
    if stat.S_ISREG(st.st_mode):
        return "file:" + hashlib.sha1(path.read_bytes()).hexdigest()
    if stat.S_ISDIR(st.st_mode):
        h = hashlib.sha1()
        for p in sorted(path.rglob("*")):
            h.update(f"{p.relative_to(path)}={digest(p) if not p.is_dir() or p.is_symlink() else 'dir'};".encode())
        return "dir:" + h.hexdigest()
    return "other"


def complete_output(out: Path) -> bool:
    """A complete sensorless output: the manifest, and every file it lists."""
    try:
        doc = json.loads((Path(out) / MANIFEST).read_text())
        return all((Path(out) / f).is_file() for f in doc["files"])
    except (OSError, ValueError, KeyError, TypeError):
        return False


def make_device(path: Path) -> bool:
    """A private character device equal to /dev/null (root only); never the real /dev/null as an output."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        return True
    except (PermissionError, OSError):
        return False


def setup_model(d: Path) -> dict:
    """Once per worker: two_link.urdf, a 300-sample simulated log and its OLS ``sensorless identify`` output."""
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    robot_file = d / "two.urdf"
    robot_file.write_text(TWO_LINK)
    robot = load_robot(robot_file)
    truth = perturbed_truth(robot, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(100, 3.0), noise_std=0.05, rng=2)
    log = write_npz(traj, d / "log.npz")
    model = d / "model"
    r = cli(["identify", "--robot", robot_file, "--data", log, "--out", model, "--method", "ols", "--no-plot",
             "--joint-terms", "fv,fc"])
    if r.exit_code != 0:
        raise RuntimeError(f"fuzz setup: identify failed: {r.output}")
    return {"robot_file": robot_file, "robot": robot, "log": log, "model": model, "traj": traj}

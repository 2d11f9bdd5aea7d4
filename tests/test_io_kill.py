"""Kill-safe replacement of an output directory (issue 26, "Kill test").

A driver process replaces a previous output (``atomic_output_dir(force=True)``, a few files in
sub-folders) and signals itself at the N-th call of the OS-level functions the writer uses
(``os.rename``/``os.replace``/``os.mkdir``/``os.unlink``/``os.rmdir``/``os.open``/``os.pwrite``/
``shutil.rmtree``/the ``renameat2`` wrapper), once per N over the whole run, including inside
the swap and inside the removal of the previous tree. After each kill one complete output (old
or new: manifest present, every listed file present with its SHA-256) must exist under OUT,
at once or after :func:`recover_output`, and nothing hidden may remain after recovery.
Both swap routes run: ``renameat2(RENAME_EXCHANGE)`` and the journal fallback (exchange made
to fail with EINVAL). SIGTERM is sent with the run in the main thread (a Python handler turns
it into SystemExit) and in a worker thread (the default action kills the process at once).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from sensorless import outdir
from sensorless.io import atomic_output_dir, atomic_write_text
from sensorless.outdir import RUN_MARKER, recover_output

SRC = str(Path(__file__).resolve().parents[1] / "src")
FILES = ("a.txt", "sub/b.txt", "sub/c.txt", "d/e/f.txt")

DRIVER = textwrap.dedent("""
    import errno, os, shutil, signal, sys, threading
    sys.path.insert(0, {src!r})
    from pathlib import Path
    from sensorless import outdir, io
    out, n, sig, mode, where = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
    calls, at = [0], [n]

    def counted(mod, name, real=None):
        real = real or getattr(mod, name)
        def f(*a, **k):
            calls[0] += 1
            if calls[0] == at[0]:
                os.kill(os.getpid(), sig)
            if at[0] == -1 and name == "rename":  # -1: between the journal's two renames
                at[0] = calls[0] + 1
            return real(*a, **k)
        setattr(mod, name, f)

    if mode == "journal":
        def unsupported(src, dst, flags):
            if flags == outdir.RENAME_EXCHANGE:
                raise OSError(errno.EINVAL, "exchange unsupported")
            return _real_renameat2(src, dst, flags)
        _real_renameat2 = outdir.renameat2
        outdir.renameat2 = unsupported
    for name in ("rename", "replace", "mkdir", "rmdir", "unlink", "open", "pwrite", "ftruncate"):
        counted(os, name)
    counted(outdir, "renameat2")
    counted(shutil, "rmtree")

    def run():
        with io.atomic_output_dir(out, force=True) as tmp:
            for i, f in enumerate({files!r}):
                io.atomic_write_text(tmp / f, f"new {{i}}\\n" * 50)

    if where == "thread":
        t = threading.Thread(target=run)
        t.start()
        t.join()
    else:
        run()
    print(calls[0], flush=True)
""")


def _write(out: Path, tag: str, force: bool = False) -> None:
    with atomic_output_dir(out, force=force) as tmp:
        for i, f in enumerate(FILES):
            atomic_write_text(tmp / f, f"{tag} {i}\n" * 50)


def _version(out: Path) -> str | None:
    """'old' or 'new' when OUT is complete (and all its files agree), else None."""
    if not outdir.is_complete(out):
        return None
    tags = {(out / f).read_text().split()[0] for f in FILES}
    return tags.pop() if len(tags) == 1 else None


def _driver(tmp_path: Path) -> Path:
    script = tmp_path / "driver.py"
    if not script.exists():
        script.write_text(DRIVER.format(src=SRC, files=FILES))
    return script


def _run(script: Path, out: Path, n: int, sig: int, mode: str, where: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(script), str(out), str(n), str(int(sig)), mode, where],
                          capture_output=True, text=True, timeout=120)


def _kill_points(tmp_path: Path, mode: str, points) -> dict:
    """Kill a --force replacement at each (signal, thread, N); return the tallies."""
    script = _driver(tmp_path)
    out = tmp_path / "work" / "run"
    tally = {"kills": {}, "points": {}, "old": 0, "new": 0, "recovered": 0, "neither": [], "finished": 0}
    for sig, where, n in points:
        if out.parent.exists():
            shutil.rmtree(out.parent)
        _write(out, "old")
        r = _run(script, out, n, sig, mode, where)
        if r.returncode == 0:  # N beyond the run's calls: it finished
            tally["finished"] += 1
            assert _version(out) == "new", r.stderr
            continue
        assert r.returncode in (-signal.SIGKILL, -signal.SIGTERM, 128 + signal.SIGTERM), (n, r.returncode, r.stderr)
        name = signal.Signals(sig).name
        tally["kills"][name] = tally["kills"].get(name, 0) + 1
        tally["points"].setdefault(name, set()).add((mode, where, n))
        got = _version(out)
        if got is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                recover_output(out)
            got = _version(out)
            tally["recovered"] += got is not None
        if got is None:
            tally["neither"].append((name, where, n, sorted(p.name for p in out.parent.iterdir())))
            continue
        tally[got] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            recover_output(out)  # what the next command does first: leftovers of the killed run go
        assert sorted(p.name for p in out.parent.iterdir()) == ["run"], (name, where, n, list(out.parent.iterdir()))
        assert _version(out) == got
    return tally


def _calls(tmp_path: Path, mode: str) -> int:
    """OS-level calls of one uninterrupted --force replacement (the kill points available)."""
    out = tmp_path / "count" / "run"
    _write(out, "old")
    r = _run(_driver(tmp_path), out, 0, signal.SIGKILL, mode, "main")
    assert r.returncode == 0, r.stderr
    assert _version(out) == "new"
    return int(r.stdout.split()[-1])


def _plan(total: int, step: int) -> list:
    ns = list(range(1, total + 1, step))
    return ([(signal.SIGKILL, "main", n) for n in ns] + [(signal.SIGTERM, "main", n) for n in ns[::2]]
            + [(signal.SIGTERM, "thread", n) for n in ns[1::2]])


@pytest.mark.parametrize("mode, points", [
    ("exchange", 20), ("journal", 12),
    pytest.param("journal", 0, marks=pytest.mark.slow)])  # exchange at 20: every one of its 39 calls
def test_kill_at_every_point_of_a_force_replacement_keeps_one_complete_output(tmp_path, mode, points):
    """``points`` kill points per signal spread over the run (0: every call)."""
    total = _calls(tmp_path, mode)
    assert total >= 20, total
    step = max(1, total // points) if points else 1
    tally = _kill_points(tmp_path, mode, _plan(total, step))
    print(mode, total, {k: v if k != "points" else {s: len(p) for s, p in v.items()} for k, v in tally.items()})
    assert tally["neither"] == []
    want = points or total
    assert len(tally["points"]["SIGKILL"]) >= want and len(tally["points"]["SIGTERM"]) >= want, tally["kills"]
    assert tally["old"] > 0 and tally["new"] > 0  # kills before and after the swap both happened
    if mode == "journal":  # and in the window between the two renames, repaired by the next command
        between = _kill_points(tmp_path, mode, [(signal.SIGKILL, "main", -1), (signal.SIGTERM, "thread", -1)])
        assert between["recovered"] == 2 and between["old"] == 2 and between["neither"] == [], between


def test_stale_lock_of_a_killed_run_is_reused_with_a_warning(tmp_path):
    out = tmp_path / "run"
    _write(out, "old")
    r = _run(_driver(tmp_path), out, 6, signal.SIGKILL, "exchange", "main")  # killed holding the lock
    assert r.returncode == -signal.SIGKILL
    lock = tmp_path / ".run.lock"
    assert lock.exists() and lock.read_text().strip().isdigit()
    with pytest.warns(UserWarning, match=r"stale lock .*\.run\.lock.* killed process"):
        _write(out, "next", force=True)
    assert _version(out) == "next" and sorted(p.name for p in tmp_path.iterdir()) == ["driver.py", "run"]


def test_missing_out_with_a_complete_previous_tree_is_restored(tmp_path):
    """The state the old two-rename swap left after a kill: OUT gone, .OUT.old-* and .OUT.tmp-* beside it."""
    out = tmp_path / "run"
    _write(out, "old")
    old = tmp_path / ".run.old-123-abcdef012345"
    os.rename(out, old)
    half = tmp_path / ".run.tmp-999999-0123456789ab"
    half.mkdir()
    (half / "a.txt").write_text("half")
    (half / RUN_MARKER).write_text("999999-0123456789ab\n")  # as a run writes it: the tree is ours
    (tmp_path / ".run.lock").write_text("999999\n")
    with pytest.warns(UserWarning, match=r"restored the output from \.run\.old-123-abcdef012345"):
        assert recover_output(out) == old.name
    assert _version(out) == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    # an incomplete previous tree (a file missing) is never restored
    os.rename(out, old)
    (old / "sub" / "b.txt").unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert recover_output(out) is None
    assert not out.exists()


def test_dead_atomic_write_temporaries_are_removed(tmp_path):
    f = tmp_path / "pred.npz"
    dead = tmp_path / ".pred.npz.999999-abcdef012345.tmp"
    live = tmp_path / f".pred.npz.{os.getpid()}-abcdef012345.tmp"
    dead.write_text("x")
    live.write_text("x")
    atomic_write_text(f, "y")
    assert not dead.exists() and live.exists() and f.read_text() == "y"


@pytest.fixture(scope="module")
def tiny_log(tmp_path_factory):
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    panda = load_robot("panda", lock_joints=["panda_finger_joint1", "panda_finger_joint2"])
    d = tmp_path_factory.mktemp("log")
    truth = perturbed_truth(panda, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(50, 10.0), noise_std=0.1, rng=2)
    write_npz(tr, d / "train.npz")
    return d / "train.npz"


def _identify_cmd(log: Path, out: Path) -> list:
    return [sys.executable, "-c", "from sensorless.cli import app; app()", "identify", "--robot", "panda",
            "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2", "--data", str(log), "--out", str(out),
            "--force"]


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""), "OPENBLAS_NUM_THREADS": "1"}


@pytest.mark.slow  # ≈ 90 s: seven CLI runs
def test_time_based_kills_of_a_real_identify_force(tiny_log, tmp_path):
    """A handful of SIGKILL/SIGTERM at spread times of `sensorless identify --force` onto a previous output."""
    import time

    out = tmp_path / "run"
    t0 = time.monotonic()
    r = subprocess.run(_identify_cmd(tiny_log, out)[:-1], env=_env(), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    duration = time.monotonic() - t0
    first = (out / "result.json").read_bytes()
    outcomes = []
    for k, frac in enumerate((0.35, 0.6, 0.8, 0.9, 0.97, 1.02)):
        sig = (signal.SIGKILL, signal.SIGTERM)[k % 2]
        p = subprocess.Popen(_identify_cmd(tiny_log, out), env=_env(), stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
        time.sleep(duration * frac)
        p.send_signal(sig)
        p.wait(timeout=600)
        if not outdir.is_complete(out):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                recover_output(out)
        outcomes.append((sig.name, p.returncode, outdir.is_complete(out)))
        assert outdir.is_complete(out), outcomes
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            recover_output(out)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["run"], outcomes
    assert first  # the first output existed; each later state is complete (old or new)
    print(outcomes)

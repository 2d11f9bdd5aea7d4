"""Outputs never clobber, environment errors are typed, concurrent writers never mix (issue 26).

* single-file ``--out`` (predict, estimate-force, payload, drive-gains): no overwrite without
  ``--force``, never an input or a file inside an input folder, never a FIFO;
* ``demo`` needs ``--force`` to replace; ``--force`` refuses edited listed files and unlisted folders;
* disk full (a real 200 KB tmpfs when mount is permitted, and a monkeypatched ENOSPC
  everywhere), read-only and permission errors: one OutputError line naming the path, nothing partial;
* 8 concurrent writers on distinct outputs and 4 on one output: complete or refused by the lock.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensorless import outdir
from sensorless.cli import app
from sensorless.errors import OutputError
from sensorless.io import atomic_output_dir, check_output_file, write_npz_atomic
from sensorless.outdir import MANIFEST, read_manifest

runner = CliRunner()
ROBOT = ["--robot", "panda", "--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def log(panda_train_npz):
    return panda_train_npz


@pytest.fixture(scope="module")
def model(log, tmp_path_factory):
    out = tmp_path_factory.mktemp("model") / "run"
    r = _run("identify", *ROBOT, "--data", log, "--out", out)
    assert r.exit_code == 0, r.output
    return out


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _error(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output)
    text = r.output.strip()
    assert "Traceback" not in text and "internal error" not in text, text
    text = text[text.rindex("error:"):].replace("\n", "")  # after any warnings and tables the command printed
    for n in needles:
        assert n in text, text


def _snapshot(d: Path) -> dict:
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


# ---- outputs never clobber ---------------------------------------------------------------
def test_predict_never_overwrites_without_force(log, model, tmp_path):
    out = tmp_path / "p.npz"
    out.write_bytes(b"previous")
    _error(_run("predict", *ROBOT, "--model", model, "--data", log, "--out", out), str(out), "--force")
    assert out.read_bytes() == b"previous"
    r = _run("predict", *ROBOT, "--model", model, "--data", log, "--out", out, "--force")
    assert r.exit_code == 0, r.output
    assert "tau_pred" in np.load(out) and sorted(p.name for p in tmp_path.iterdir()) == ["p.html", "p.npz", "p.png"]


@pytest.mark.parametrize("cmd", ["predict", "estimate-force"])
def test_out_inside_the_model_folder_is_refused(log, model, cmd, tmp_path):
    before = _snapshot(model)
    extra = ["--frame", "panda_hand"] if cmd == "estimate-force" else []
    for m, target in ((model, model / "result.json"), (model, model / "new.npz"), (model / "result.json", model / "x.npz")):
        r = _run(cmd, *ROBOT, "--model", m, "--data", log, "--out", target, "--force", *extra)
        _error(r, str(target))
        assert "input" in r.output
    assert _snapshot(model) == before


def test_payload_out_onto_the_model_is_refused(log, model):
    before = _snapshot(model)
    r = _run("payload", *ROBOT, "--model", model, "--data", log, "--frame", "panda_hand",
             "--out", model / "result.json", "--force")
    _error(r, str(model / "result.json"), "input")
    assert _snapshot(model) == before


@pytest.mark.parametrize("cmd", ["predict", "estimate-force"])
def test_fifo_out_is_refused_and_stays_a_fifo(log, model, cmd, tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    extra = ["--frame", "panda_hand"] if cmd == "estimate-force" else []
    _error(_run(cmd, *ROBOT, "--model", model, "--data", log, "--out", fifo, "--force", *extra), str(fifo), "FIFO")
    assert fifo.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]
    with pytest.raises(OutputError, match="FIFO"):
        write_npz_atomic(fifo, x=np.zeros(2))  # the library refuses too
    assert fifo.is_fifo()


def test_check_output_file_rules(tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    (d / "log.csv").write_text("x")
    with pytest.raises(OutputError, match="inside the input folder"):
        check_output_file(d / "log.csv", [d], force=True)  # an existing file in an input folder
    assert check_output_file(d / "out.npz", [d]) == d / "out.npz"  # a new file next to plain inputs
    (d / MANIFEST).write_text("{}")  # a sensorless output folder: nothing is written into it
    with pytest.raises(OutputError, match="inside the input folder"):
        check_output_file(d / "out.npz", [d])
    (tmp_path / "f.npz").write_text("x")
    with pytest.raises(OutputError, match="`force=True`"):
        check_output_file(tmp_path / "f.npz")
    assert check_output_file(tmp_path / "f.npz", force=True) == tmp_path / "f.npz"
    assert check_output_file(tmp_path / "g.npz", [d / "log.csv"]) == tmp_path / "g.npz"  # a plain folder's sibling file


def test_demo_needs_force_to_replace(tmp_path, monkeypatch):
    import sensorless_studies.demo as demo

    def tiny(out, seed=0, console=None):
        (Path(out) / "result.json").write_text(json.dumps({"seed": seed}))

    monkeypatch.setattr(demo, "run_demo", tiny)
    out = tmp_path / "demo_output"
    assert _run("demo", "--out", out).exit_code == 0
    before = _snapshot(out)
    _error(_run("demo", "--out", out, "--seed", "1"), str(out), "--force")
    assert _snapshot(out) == before
    r = _run("demo", "--out", out, "--seed", "1", "--force")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "result.json").read_text()) == {"seed": 1}
    assert "demo --out demo_output --force" in (Path(__file__).resolve().parents[1] / "Makefile").read_text()


def _make(out: Path, tag: str, force: bool = False) -> None:
    with atomic_output_dir(out, force=force) as tmp:
        (tmp / "result.txt").write_text(tag)
        (tmp / "sub").mkdir()
        (tmp / "sub" / "x.txt").write_text(tag)


def test_force_refuses_edited_files_and_unlisted_folders(tmp_path):
    out = tmp_path / "run"
    _make(out, "first")
    man = read_manifest(out)
    assert man["hashes"]["sub/x.txt"]["size"] == 5 and len(man["hashes"]["sub/x.txt"]["sha256"]) == 64
    assert man["dirs"] == ["sub"]
    (out / "sub" / "x.txt").write_text("my notes")  # the user edited a listed file
    with pytest.raises(OutputError, match=r"sub/x\.txt was changed"):
        _make(out, "second", force=True)
    assert (out / "sub" / "x.txt").read_text() == "my notes"
    (out / "sub" / "x.txt").write_text("first")
    (out / "mine").mkdir()  # an empty folder the user made
    with pytest.raises(OutputError, match="folder mine"):
        _make(out, "second", force=True)
    assert (out / "mine").is_dir()
    (out / "mine").rmdir()
    (out / "result.txt").unlink()  # a listed file deleted by the user: nothing to lose
    _make(out, "second", force=True)
    assert (out / "result.txt").read_text() == "second" and outdir.is_complete(out)


# ---- environment errors --------------------------------------------------------------------
def _no_hidden(d: Path) -> None:
    assert not [p for p in d.rglob(".*") if p.name != MANIFEST], list(d.rglob(".*"))


@pytest.fixture
def tiny_fs(tmp_path):
    """A 200 KB tmpfs (root only; skipped where mounting is not permitted)."""
    d = tmp_path / "full"
    d.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(d)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {r.stderr.decode().strip()}")
    yield d
    subprocess.run(["umount", "-l", str(d)], check=False)


def _fill(d: Path, leave: int) -> None:
    """Fill the file system of ``d`` until about ``leave`` bytes are free."""
    st = os.statvfs(d)
    free = st.f_bavail * st.f_frsize
    with open(d / "filler", "wb") as fh:
        try:
            fh.write(b"\0" * max(0, free - leave))
        except OSError:
            pass


def test_disk_full_identify_is_one_line_and_leaves_nothing(log, tiny_fs):
    _fill(tiny_fs, 16 * 1024)
    out = tiny_fs / "run"
    r = _run("identify", *ROBOT, "--data", log, "--out", out)
    _error(r, str(out), "No space left on device")
    assert sorted(p.name for p in tiny_fs.iterdir()) == ["filler"]


def test_disk_full_force_replace_keeps_the_previous_output(log, model, tiny_fs):
    out = tiny_fs / "run"
    _make(out, "previous")
    _fill(tiny_fs, 8 * 1024)
    r = _run("identify", *ROBOT, "--data", log, "--out", out, "--force")
    _error(r, str(out), "No space left on device")
    assert (out / "result.txt").read_text() == "previous" and outdir.is_complete(out)
    _no_hidden(tiny_fs)
    r = _run("predict", *ROBOT, "--model", model, "--data", log, "--out", tiny_fs / "p.npz")
    _error(r, str(tiny_fs / "p.npz"), "No space left on device")
    assert sorted(p.name for p in tiny_fs.iterdir()) == ["filler", "run"]


def test_enospc_anywhere_is_a_typed_error_naming_out(tmp_path, monkeypatch):
    """Monkeypatched ENOSPC (runs without a tmpfs): while the command writes, at the manifest, at a file."""
    out = tmp_path / "run"

    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OutputError, match=rf"^{out}.*No space left on device"):
        with atomic_output_dir(out) as tmp:
            with monkeypatch.context() as m:
                m.setattr(np, "savez", full)
                write_npz_atomic(tmp / "a.npz", x=np.zeros(3))
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    _make(out, "previous")
    with monkeypatch.context() as m:
        real = outdir.digest
        m.setattr(outdir, "digest", lambda p: full() if ".run.tmp-" in str(p) else real(p))  # writing the manifest
        with pytest.raises(OutputError, match=rf"^{out}: cannot write: No space left on device"):
            _make(out, "new", force=True)
    assert (out / "result.txt").read_text() == "previous" and sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_monitor_disk_full_is_a_typed_error(log, model, tmp_path, monkeypatch):
    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(np, "savez", full)
    out = tmp_path / "mon"
    r = _run("monitor", *ROBOT, "--model", model, "--data", log, "--out", out)
    _error(r, str(out), "No space left on device")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_read_only_file_system_is_a_typed_error(tmp_path, tiny_fs):
    subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], check=True)
    for target in (tiny_fs / "run", tiny_fs / "sub" / "run"):
        with pytest.raises(OutputError, match=rf"{tiny_fs}.*Read-only file system"):
            _make(target, "x")
    with pytest.raises(OutputError, match=rf"{tiny_fs}.*Read-only file system"):
        write_npz_atomic(tiny_fs / "a" / "p.npz", x=np.zeros(2))
    assert list(tiny_fs.iterdir()) == []


# ---- concurrency --------------------------------------------------------------------------
WRITER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {src!r})
    from pathlib import Path
    from sensorless.errors import OutputError
    from sensorless.io import atomic_output_dir
    out, tag, go = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
    while not go.exists():
        time.sleep(0.005)
    try:
        with atomic_output_dir(out, force=True) as tmp:
            for i in range(5):
                (tmp / f"f{{i}}.txt").write_text(tag * 1000)
                time.sleep(0.02)
    except OutputError as exc:
        print(exc, flush=True)
        sys.exit(2)
""")


def test_eight_distinct_and_four_same_output_writers(tmp_path):
    script = tmp_path / "writer.py"
    script.write_text(WRITER.format(src=SRC))
    go = tmp_path / "go"
    same = tmp_path / "same"
    _make(same, "0", force=False)
    jobs = [(tmp_path / f"d{i}", f"D{i}") for i in range(8)] + [(same, f"S{i}") for i in range(4)]
    procs = [subprocess.Popen([sys.executable, str(script), str(o), t, str(go)], stdout=subprocess.PIPE, text=True)
             for o, t in jobs]
    time.sleep(1.0)
    go.touch()
    results = [(o, t, p.communicate(timeout=120)[0], p.returncode) for (o, t), p in zip(jobs, procs)]
    for o, t, _, code in results[:8]:
        assert code == 0 and outdir.is_complete(o) and {f.read_text()[:2] for f in o.glob("f*.txt")} == {t}
    codes = [code for *_, code in results[8:]]
    assert set(codes) <= {0, 2} and 0 in codes, results[8:]
    for _, _, msg, code in results[8:]:
        assert code == 0 or "another sensorless run" in msg, msg
    winners = {t for _, t, _, code in results[8:] if code == 0}
    tags = {f.read_text()[:2] for f in same.glob("f*.txt")}
    assert outdir.is_complete(same) and len(tags) == 1 and tags <= winners and len(list(same.glob("f*.txt"))) == 5
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
    print({"distinct_complete": 8, "same_succeeded": len(winners), "same_refused": codes.count(2)})


@pytest.mark.slow  # twelve CLI processes at once on a tiny log
def test_concurrent_identify_runs(log, tmp_path):
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""), "OPENBLAS_NUM_THREADS": "1"}
    same = tmp_path / "same"
    jobs = [tmp_path / f"d{i}" for i in range(8)] + [same] * 4
    procs = [subprocess.Popen([sys.executable, "-c", "from sensorless.cli import app; app()", "identify", *ROBOT,
                               "--data", str(log), "--out", str(o), "--force"], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for o in jobs]
    results = [(o, p.communicate(timeout=1200)[1], p.returncode) for o, p in zip(jobs, procs)]
    for o, err, code in results[:8]:
        assert code == 0 and outdir.is_complete(o), err
    codes = [code for *_, code in results[8:]]
    assert set(codes) <= {0, 2} and 0 in codes and outdir.is_complete(same), results[8:]
    assert all(code == 0 or "another sensorless run" in err for _, err, code in results[8:])
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    print({"distinct_complete": 8, "same_succeeded": codes.count(0), "same_refused": codes.count(2)})

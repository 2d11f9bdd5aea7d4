"""sensorless.io: atomic files and output directories that never destroy what the tool did not write.

Every refusal test puts a canary file where a careless ``rmtree`` would delete it and
checks that it survives, even with ``force=True``.
"""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from sensorless.errors import OutputError, SensorlessError
from sensorless.outdir import MANIFEST, read_manifest
from sensorless.io import (
    atomic_open,
    atomic_output_dir,
    atomic_write_text,
    check_output_file,
    write_json_atomic,
    write_npz_atomic,
)

SRC = str(Path(__file__).resolve().parents[1] / "src")


def _strict_loads(text: str):
    def no_constants(name):
        raise AssertionError(f"invalid JSON constant {name}")

    return json.loads(text, parse_constant=no_constants)


def _canary(d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    f = d / "canary.txt"
    f.write_text("alive")
    return f


def _make_output(out: Path, marker: str = "first", force: bool = False) -> None:
    with atomic_output_dir(out, force=force) as tmp:
        (tmp / "result.txt").write_text(marker)
        (tmp / "sub").mkdir()
        (tmp / "sub" / "x.txt").write_text("x")


def _no_leftovers(out: Path) -> None:
    assert not list(out.parent.glob(f".{out.name}.*")), list(out.parent.iterdir())


@pytest.fixture
def umask022():
    old = os.umask(0o022)
    yield
    os.umask(old)


# ---- files ---------------------------------------------------------------------------------
def test_json_non_finite_is_null_and_strict(tmp_path):
    f = tmp_path / "r.json"
    write_json_atomic({"condition_number": float("nan"), "a": np.array([1.0, np.inf, -np.inf]), "b": np.float64("nan"),
                       "n": np.int64(3), "ok": np.bool_(True), "p": tmp_path}, f)
    doc = _strict_loads(f.read_text())
    assert doc == {"condition_number": None, "a": [1.0, None, None], "b": None, "n": 3, "ok": True, "p": str(tmp_path)}


def test_identification_result_json_has_no_bare_nan(tmp_path, panda):
    from sensorless.excitation import random_fourier
    from sensorless.identification import identify
    from sensorless.regressor import ModelStructure
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    truth = perturbed_truth(panda, rng=0)
    traj = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(50, 10.0), noise_std=0.05, rng=2)
    res = identify(ModelStructure(panda), traj)
    res.diagnostics["condition_number"] = float("nan")  # what an ill-posed problem used to write as bare NaN
    res.save_json(tmp_path / "result.json")
    doc = _strict_loads((tmp_path / "result.json").read_text())
    assert doc["diagnostics"]["condition_number"] is None
    assert all(np.isfinite(v) for v in doc["parameters"].values())


def test_file_permissions_follow_umask(tmp_path, umask022):
    write_json_atomic({"a": 1}, tmp_path / "a.json")
    write_npz_atomic(tmp_path / "a.npz", x=np.arange(3))
    atomic_write_text(tmp_path / "a.txt", "x")
    for name in ("a.json", "a.npz", "a.txt"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644, name
    os.umask(0o027)
    write_json_atomic({"a": 1}, tmp_path / "b.json")
    assert stat.S_IMODE((tmp_path / "b.json").stat().st_mode) == 0o640


def test_npz_is_written_to_the_exact_name(tmp_path):
    out = write_npz_atomic(tmp_path / "pred.data", x=np.arange(4))
    assert out == tmp_path / "pred.data" and sorted(p.name for p in tmp_path.iterdir()) == ["pred.data"]
    np.testing.assert_array_equal(np.load(out)["x"], np.arange(4))


def test_failed_file_write_leaves_old_file_and_no_temp(tmp_path):
    f = tmp_path / "keep.txt"
    f.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_open(f) as fh:
            fh.write("half")
            raise RuntimeError("boom")
    assert f.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_file_into_a_directory_or_an_input_is_refused(tmp_path):
    d = tmp_path / "dir"
    _canary(d)
    with pytest.raises(OutputError, match="is a directory"):
        write_npz_atomic(d, x=np.arange(2))
    with pytest.raises(OutputError, match="is a directory"):
        check_output_file(d)
    log = tmp_path / "log.npz"
    log.write_bytes(b"data")
    with pytest.raises(OutputError, match="input"):
        check_output_file(tmp_path / "." / "log.npz", [log])
    assert sorted(p.name for p in d.iterdir()) == ["canary.txt"] and log.read_bytes() == b"data"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir", "log.npz"]


def test_unwritable_file_is_a_typed_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="file"):
        write_json_atomic({"a": 1}, blocker / "sub" / "r.json")


# ---- output directories ----------------------------------------------------------------------
def test_output_dir_has_manifest_and_umask_permissions(tmp_path, umask022):
    out = tmp_path / "run"
    _make_output(out)
    man = read_manifest(out)
    assert man is not None and man["tool"] == "sensorless" and man["files"] == ["result.txt", "sub/x.txt"]
    assert _strict_loads((out / MANIFEST).read_text())["created"]
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    assert stat.S_IMODE((out / "sub").stat().st_mode) == 0o755
    assert stat.S_IMODE((out / MANIFEST).stat().st_mode) == 0o644
    _no_leftovers(out)


def test_existing_output_is_untouched_without_force(tmp_path):
    out = tmp_path / "run"
    _make_output(out, "first")
    with pytest.raises(OutputError, match="`force=True`"):
        _make_output(out, "second")
    assert (out / "result.txt").read_text() == "first"
    _no_leftovers(out)


def test_force_replaces_a_previous_output(tmp_path):
    out = tmp_path / "run"
    _make_output(out, "first")
    with atomic_output_dir(out, force=True) as tmp:
        (tmp / "result.txt").write_text("second")
    assert (out / "result.txt").read_text() == "second"
    assert not (out / "sub").exists(), "the previous output is replaced, not merged"
    assert read_manifest(out)["files"] == ["result.txt"]
    _no_leftovers(out)


def test_failure_leaves_previous_output_and_no_temp(tmp_path):
    out = tmp_path / "run"
    _make_output(out, "first")
    with pytest.raises(RuntimeError):
        with atomic_output_dir(out, force=True) as tmp:
            (tmp / "result.txt").write_text("second")
            raise RuntimeError("solver failed")
    assert (out / "result.txt").read_text() == "first"
    _no_leftovers(out)


@pytest.mark.parametrize("case", ["dot", "dotdot", "home", "cwd_abs", "ancestor", "foreign", "input", "extra_file",
                                  "symlink", "is_file", "fake_manifest"])
def test_force_never_deletes_what_the_tool_did_not_write(tmp_path, monkeypatch, case):
    work = tmp_path / "a" / "work"
    canaries = [_canary(work), _canary(tmp_path / "a"), _canary(tmp_path)]
    monkeypatch.chdir(work)
    inputs = []
    if case == "dot":
        out = Path(".")
    elif case == "dotdot":
        out = Path("..")
    elif case == "home":
        home = tmp_path / "home"
        canaries.append(_canary(home))
        monkeypatch.setenv("HOME", str(home))
        out = Path("~").expanduser()
    elif case == "cwd_abs":
        out = work
    elif case == "ancestor":
        out = tmp_path / "a"
    elif case == "foreign":
        out = tmp_path / "mine"
        canaries.append(_canary(out))
    elif case == "input":  # a genuine previous output that holds this run's input log
        out = tmp_path / "prev"
        _make_output(out)
        inputs = [out / "sub" / "x.txt"]
        canaries.append(out / "result.txt")
    elif case == "extra_file":  # a previous output the user has since added a file to
        out = tmp_path / "prev"
        _make_output(out)
        canaries.append(_canary(out))
    elif case == "symlink":
        target = tmp_path / "prev"
        _make_output(target)
        canaries.append(target / "result.txt")
        out = tmp_path / "link"
        out.symlink_to(target)
    elif case == "is_file":
        out = tmp_path / "canary.txt"
    elif case == "fake_manifest":
        out = tmp_path / "fake"
        canaries.append(_canary(out))
        (out / MANIFEST).write_text('{"tool": "something-else", "files": ["canary.txt"]}')
    with pytest.raises(OutputError) as err:
        with atomic_output_dir(out, force=True, inputs=inputs) as tmp:
            (tmp / "result.txt").write_text("new")
    assert str(out) in str(err.value)
    for c in canaries:
        assert c.exists(), f"{c} was deleted"
    assert not list(tmp_path.rglob(".*.tmp-*")) and not list(tmp_path.rglob(".*.lock"))


def test_root_is_refused():
    with pytest.raises(OutputError, match="root"):
        with atomic_output_dir(Path("/"), force=True):
            pass


def test_unwritable_output_dir_is_a_typed_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="cannot create"):
        with atomic_output_dir(blocker / "out"):
            pass
    assert blocker.read_text() == "x"


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_read_only_parent_is_a_typed_error(tmp_path):
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)
    try:
        with pytest.raises(OutputError):
            with atomic_output_dir(parent / "out"):
                pass
    finally:
        parent.chmod(0o755)


# ---- concurrency -----------------------------------------------------------------------------
def test_concurrent_run_in_a_thread_fails_clearly(tmp_path):
    out = tmp_path / "run"
    inside, release, errors = threading.Event(), threading.Event(), []

    def first():
        try:
            with atomic_output_dir(out) as tmp:
                (tmp / "result.txt").write_text("first")
                inside.set()
                release.wait(10)
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)
            inside.set()

    t = threading.Thread(target=first)
    t.start()
    assert inside.wait(10)
    for force in (False, True):
        with pytest.raises(OutputError, match="another sensorless run"):
            _make_output(out, "second", force=force)
    release.set()
    t.join(10)
    assert not errors and (out / "result.txt").read_text() == "first"
    _make_output(out, "third", force=True)  # once the first run is done, --force replaces it properly
    assert (out / "result.txt").read_text() == "third"
    _no_leftovers(out)


_WRITER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    sys.path.insert(0, {src!r})
    from sensorless.errors import SensorlessError
    from sensorless.io import atomic_output_dir
    out, tag, release = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
    try:
        with atomic_output_dir(out, force=True) as tmp:
            (tmp / "result.txt").write_text(tag)
            print("ready", flush=True)
            deadline = time.monotonic() + 120
            while not release.exists() and time.monotonic() < deadline:
                time.sleep(0.02)
    except SensorlessError as exc:
        print(f"error: {{exc}}", flush=True)
        sys.exit(2)
""")


def _writer(tmp_path: Path, out: Path, tag: str) -> subprocess.Popen:
    """A process that writes ``out`` and holds it until ``tmp_path/release`` exists."""
    script = tmp_path / "writer.py"
    if not script.exists():
        script.write_text(_WRITER.format(src=SRC))
    return subprocess.Popen([sys.executable, str(script), str(out), tag, str(tmp_path / "release")],
                            stdout=subprocess.PIPE, text=True)


def test_two_processes_on_one_output_never_both_succeed(tmp_path):
    out = tmp_path / "run"
    _make_output(out, "previous")
    procs = [_writer(tmp_path, out, tag) for tag in ("A", "B")]
    deadline = time.monotonic() + 120
    while all(p.poll() is None for p in procs):  # the loser gives up at once; the winner holds the output
        assert time.monotonic() < deadline, "neither run gave up"
        time.sleep(0.05)
    (tmp_path / "release").touch()
    outputs = [p.communicate(timeout=60)[0] for p in procs]
    codes = [p.returncode for p in procs]
    assert sorted(codes) == [0, 2], (codes, outputs)
    winner = "AB"[codes.index(0)]
    loser_msg = outputs[codes.index(2)]
    assert "another sensorless run" in loser_msg and str(out) in loser_msg
    assert (out / "result.txt").read_text() == winner  # the reported success is what is on disk
    _no_leftovers(out)


def test_sigterm_leaves_no_temporary_directory(tmp_path):
    out = tmp_path / "run"
    p = _writer(tmp_path, out, "A")
    assert p.stdout.readline().strip() == "ready"
    assert list(tmp_path.glob(".run.tmp-*")), "the run should be writing into a hidden temporary directory"
    p.send_signal(signal.SIGTERM)
    p.communicate(timeout=30)
    assert p.returncode == 128 + signal.SIGTERM
    assert not out.exists()
    _no_leftovers(out)


def test_sigterm_during_replacement_keeps_previous_output(tmp_path):
    out = tmp_path / "run"
    _make_output(out, "previous")
    p = _writer(tmp_path, out, "A")
    assert p.stdout.readline().strip() == "ready"
    p.terminate()
    p.communicate(timeout=30)
    assert (out / "result.txt").read_text() == "previous"
    _no_leftovers(out)
    # and a new run can still take the lock
    _make_output(out, "next", force=True)
    assert (out / "result.txt").read_text() == "next"


def test_output_error_is_a_sensorless_error():
    assert issubclass(OutputError, SensorlessError)


def test_write_npz_is_atomic_and_exact(tmp_path, monkeypatch):
    """write_npz writes exactly PATH (no '.npz' appended, no temp left); a failed write keeps the old file."""
    from sensorless.data import Trajectory, write_npz

    t = np.arange(5) * 0.01
    traj = Trajectory(t=t, q=np.zeros((5, 2)), v=np.zeros((5, 2)), a=np.zeros((5, 2)), tau=np.ones((5, 2)),
                      joint_names=("a", "b"))
    out = write_npz(traj, tmp_path / "log.bin")
    assert out == tmp_path / "log.bin" and sorted(p.name for p in tmp_path.iterdir()) == ["log.bin"]
    before = out.read_bytes()

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(RuntimeError):
        write_npz(traj, out)
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["log.bin"]


def test_malformed_learned_model_description_is_a_data_error(tmp_path):
    """A model.json that parses but lacks keys (e.g. 'params') is a DataError naming the folder."""
    import json

    pytest.importorskip("torch")
    from sensorless.learning.io import save_network
    from sensorless.learning.models import LearnedTorqueModel
    from sensorless.errors import DataError

    from sensorless.learning.mlp import build_network

    arch = {"kind": "mlp", "in_dim": 2, "out_dim": 2, "hidden": [4], "activation": "relu"}
    d = save_network(tmp_path / "m", build_network(arch), {"type": "LearnedTorqueModel", "architecture": arch})
    meta = json.loads((d / "model.json").read_text())
    meta.pop("params", None)
    (d / "model.json").write_text(json.dumps(meta))
    with pytest.raises(DataError, match="incomplete or malformed"):
        LearnedTorqueModel.load(d)


def test_a_termination_swallowed_inside_the_run_still_leaves_no_output(tmp_path):
    """Clarabel polls for signals during a solve and turns the handler's SystemExit into a stopped
    solve: the run then 'finishes'. The request to terminate must still win (a CI run of the demo
    exited 0 with a complete output after SIGTERM)."""
    import os
    import signal

    from sensorless.io import atomic_output_dir

    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        with atomic_output_dir(out) as tmp:
            (tmp / "a.txt").write_text("partial")
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                for _ in range(1000):  # the handler runs at the next bytecode boundary
                    pass
            except SystemExit:
                pass  # swallowed, as a C extension's signal check would
            (tmp / "b.txt").write_text("after")
    assert exc.value.code == 128 + signal.SIGTERM
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_versions_name_the_loaded_packages_without_reading_every_packages_metadata():
    """Issue 28: a result's versions come from the loaded modules' ``__version__`` (the distributions'
    own strings), without importing importlib.metadata (~30 ms of every identify); a package the
    process did not load is not named."""
    code = ("import sys, numpy, scipy, pinocchio\nfrom sensorless.io import versions\nv = versions()\n"
            "print('importlib.metadata' in sys.modules, 'cvxpy' in v)\nimport importlib.metadata as md\n"
            "print(all(v[k] == md.version(d) for k, d in [('sensorless', 'sensorless'), ('pin', 'pin'), "
            "('numpy', 'numpy'), ('scipy', 'scipy')]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False", "True"], out.stdout

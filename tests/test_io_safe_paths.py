"""Issue #41 reproducers: no file touched that is not ours (symlinked lock and journal, user folders with
look-alike names, a planted journal, an output inside an input)."""

from __future__ import annotations

import json
import os
import warnings

import pytest

from sensorless.errors import OutputError
from sensorless.io import atomic_output_dir, atomic_write_text
from sensorless.outdir import MANIFEST, recover_output


def _write(out, text="v", **kw):
    with atomic_output_dir(out, **kw) as tmp:
        (tmp / "a.txt").write_text(text)


def test_symlinked_lock_is_refused_not_followed(tmp_path):
    """Reproducer: a symlink named `.OUT.lock` was followed; its target truncated and overwritten with the PID."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    (tmp_path / ".run.lock").symlink_to(victim)
    with pytest.raises(OutputError, match=r"\.run\.lock \(the lock file\) is a symbolic link"):
        _write(tmp_path / "run")
    assert victim.read_text() == "precious\n" and not (tmp_path / "run").exists()
    (tmp_path / ".run.lock").unlink()
    os.mkfifo(tmp_path / ".run.lock")  # a FIFO there: refused, never blocks
    with pytest.raises(OutputError, match="not a regular file"):
        _write(tmp_path / "run")


def test_user_folders_with_lookalike_names_survive(tmp_path):
    """Reproducer: any run on OUT deleted user folders named `.OUT.old-*` or `.OUT.tmp-*`. Only trees with a
    run id that this tool marked (or a sensorless manifest) of a dead process are removed."""
    out = tmp_path / "run"
    mine = {}
    for name in (".run.old-mine", ".run.tmp-notes", ".run.tmp-999999-0123456789ab", ".run.old-999999-0123456789ab"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "thesis.tex").write_text(name)
        mine[name] = tmp_path / name / "thesis.tex"
    (tmp_path / ".run.999999-0123456789ab.tmp").mkdir()  # a folder with an atomic-write temp's name
    _write(out)
    _write(out, "w", force=True)
    for name, f in mine.items():
        assert f.read_text() == name
    assert (tmp_path / ".run.999999-0123456789ab.tmp").is_dir()
    leftover = tmp_path / ".run.tmp-999999-abcdef012345"  # a dead run's tree, marked as it writes it
    leftover.mkdir()
    (leftover / ".sensorless-run").write_text("999999-abcdef012345\n")
    (leftover / "x.npz").write_text("half")
    recover_output(out)
    assert not leftover.exists() and all(f.exists() for f in mine.values())


def test_planted_journal_cannot_move_an_output_elsewhere(tmp_path):
    """Reproducer: a planted journal could move, then delete, an output in another folder."""
    other = tmp_path / "other"
    other.mkdir()
    theirs = other / ".run.old-999999-0123456789ab"
    _write(theirs, "theirs")
    here = tmp_path / "here"
    here.mkdir()
    journal = {"out": "run", "old": "../other/.run.old-999999-0123456789ab", "new": "../other/x", "pid": 999999}
    (here / ".run.journal").write_text(json.dumps(journal))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert recover_output(here / "run") is None
    assert (theirs / "a.txt").read_text() == "theirs" and (theirs / MANIFEST).is_file()
    assert not (here / "run").exists() and (here / ".run.journal").is_file()  # not ours: left alone
    (here / ".run.journal").unlink()
    target = tmp_path / "target.json"  # a journal that is a symlink is not read through
    target.write_text(json.dumps({**journal, "old": ".run.old-999999-0123456789ab"}))
    (here / ".run.journal").symlink_to(target)
    recover_output(here / "run")
    assert target.exists() and not (here / "run").exists() and (here / ".run.journal").is_symlink()


def test_a_user_file_named_like_the_lock_is_not_overwritten(tmp_path):
    """A regular file at `.OUT.lock` that holds something else than a process id is the user's."""
    (tmp_path / ".run.lock").write_text("my notes\n")
    with pytest.raises(OutputError, match="not a sensorless lock file"):
        _write(tmp_path / "run")
    assert (tmp_path / ".run.lock").read_text() == "my notes\n"


def test_no_output_inside_an_input(tmp_path):
    """Reproducer: `monitor --out model/mon` wrote inside the model folder it read."""
    model = tmp_path / "model"
    _write(model, "model")
    with pytest.raises(OutputError, match="inside the input folder"):
        _write(model / "mon", inputs=[model])
    with pytest.raises(OutputError, match="inside the input folder"):
        _write(model / "mon", inputs=[model / "a.txt"])  # a file of a sensorless output protects its folder
    data = tmp_path / "logs"
    data.mkdir()
    with pytest.raises(OutputError, match="inside the input folder"):
        _write(data / "out", inputs=[data])
    assert sorted(p.name for p in model.iterdir()) == [MANIFEST, "a.txt"]


def test_atomic_write_never_follows_or_removes_foreign_names(tmp_path):
    f = tmp_path / "pred.npz"
    victim = tmp_path / "victim"
    victim.write_text("keep")
    f.symlink_to(victim)
    atomic_write_text(f, "new")  # the link is replaced by the file, its target untouched
    assert victim.read_text() == "keep" and not f.is_symlink() and f.read_text() == "new"
    odd = tmp_path / ".pred.npz.999999-x.tmp"  # no run id: not ours
    odd.write_text("user")
    atomic_write_text(f, "again")
    assert odd.read_text() == "user"


def test_a_file_edited_after_the_run_is_named(tmp_path):
    """Reproducer: tampered values inside the readers' caps (a 150 kg wrist link, friction 1e6, a residual
    scaler of 1e300) were applied silently. A file of a sensorless output whose SHA-256 differs from the
    manifest is named in a warning when it is read, also in a sub-folder."""
    from sensorless.outdir import warn_if_edited

    out = tmp_path / "model"
    with atomic_output_dir(out) as tmp:
        (tmp / "result.json").write_text('{"m": 1.0}')
        (tmp / "residual").mkdir()
        (tmp / "residual" / "model.json").write_text('{"scale": 1.0}')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not warn_if_edited(out / "result.json") and not warn_if_edited(out / "residual" / "model.json")
    (out / "result.json").write_text('{"m": 150.0}')
    (out / "residual" / "model.json").write_text('{"scale": 1e300}')
    with pytest.warns(UserWarning, match=r"result\.json: this model file was changed since sensorless wrote it"):
        assert warn_if_edited(out / "result.json", "model file")
    with pytest.warns(UserWarning, match=r"residual/model\.json: this file was changed"):
        assert warn_if_edited(out / "residual" / "model.json")

"""Output directories on disk: manifest with hashes, lock with PID, kill-safe swap and recovery.

The swap of a new tree into ``OUT`` (used by :func:`sensorless.io.atomic_output_dir`):

* Linux: ``renameat2(tmp, OUT, RENAME_EXCHANGE)`` exchanges the two trees in one system call,
  so at every instant ``OUT`` is either the complete previous output or the complete new one,
  whatever thread receives a signal and whether the process is killed with SIGKILL. The old
  tree, now under the temporary name, is then removed; a kill during that removal leaves a
  hidden ``.OUT.tmp-*`` that the next command touching ``OUT`` deletes.
* Elsewhere (or on file systems without it, EINVAL/ENOSYS): a journal ``.OUT.journal``
  records the planned renames ``OUT → .OUT.old-*`` and ``.OUT.tmp-* → OUT`` before they
  happen; :func:`recover_output` (run by every :func:`atomic_output_dir` on ``OUT`` before it
  does anything) restores the previous output when a kill fell between them.

"Complete" means: a valid manifest, and every file it lists present with the recorded
SHA-256. Only complete trees are ever restored. Leftover ``.OUT.tmp-*``/``.OUT.old-*``
trees and atomic-write ``.tmp`` files of dead processes are removed under the lock.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import fcntl
import hashlib
import json
import os
import platform
import secrets
import shutil
import sys
import time
import warnings
from pathlib import Path
from typing import Iterator

from .errors import OutputError, SensorlessWarning

MANIFEST = ".sensorless-output.json"
TOOL = "sensorless"
RENAME_NOREPLACE, RENAME_EXCHANGE = 1, 2
_AT_FDCWD = -100
_SYSCALL = {"x86_64": 316, "aarch64": 276, "riscv64": 276, "i686": 353, "i386": 353, "armv7l": 382, "ppc64le": 357,
            "s390x": 347}
_UNSUPPORTED = (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP)


# ---- manifest ------------------------------------------------------------------------------
def read_manifest(directory: str | os.PathLike) -> dict | None:
    """The manifest of a sensorless output directory, or None when there is none (or it is not ours)."""
    f = Path(directory) / MANIFEST
    try:
        doc = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("tool") != TOOL or not isinstance(doc.get("files"), list):
        return None
    return doc


def tree(directory: Path) -> tuple[list[str], list[str]]:
    """(every non-directory entry, every real sub-directory) below ``directory``, relative, sorted
    (symlinks are entries, never followed)."""
    files, dirs = [], []
    for root, subdirs, names in os.walk(directory):
        rel = Path(root).relative_to(directory)
        files += [(rel / f).as_posix() for f in names]
        for d in subdirs:
            (files if (Path(root) / d).is_symlink() else dirs).append((rel / d).as_posix())
    return sorted(files), sorted(dirs)


def digest(path: Path) -> dict:
    """``{"size", "sha256"}`` of a file (a symlink: of its target string, not followed)."""
    h = hashlib.sha256()
    if path.is_symlink():
        target = os.fsencode(os.readlink(path))
        h.update(b"symlink:" + target)
        return {"size": len(target), "sha256": h.hexdigest()}
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return {"size": os.stat(path).st_size, "sha256": h.hexdigest()}


def changed_file(directory: Path, doc: dict, missing_ok: bool) -> str | None:
    """The first listed file whose size or SHA-256 differs from the manifest (or is missing,
    unless ``missing_ok``); None when every listed file is as sensorless wrote it."""
    hashes = doc.get("hashes") if isinstance(doc.get("hashes"), dict) else {}
    for name in doc["files"]:
        p = directory / str(name)
        if not (p.exists() or p.is_symlink()):
            if missing_ok:
                continue
            return str(name)
        want = hashes.get(name)
        if isinstance(want, dict):
            try:
                if os.lstat(p).st_size != want.get("size") or digest(p)["sha256"] != want.get("sha256"):
                    return str(name)
            except OSError:
                return str(name)
    return None


def is_complete(directory: Path) -> bool:
    """A valid manifest, and every file it lists present with its recorded hash."""
    doc = read_manifest(directory)
    return doc is not None and directory.is_dir() and not directory.is_symlink() and \
        changed_file(directory, doc, missing_ok=False) is None


# ---- lock --------------------------------------------------------------------------------
def pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _read_pid(fd: int) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        return int(text) if text.isdigit() else None
    except OSError:
        return None


@contextlib.contextmanager
def lock(out: Path) -> Iterator[None]:
    """Exclusive, non-blocking ``flock`` on ``.<name>.lock`` next to ``out``, holding this PID; removed on exit.

    A lock file left by a killed run (its flock died with it) is reused, with a warning naming
    the dead PID. A lock still held although its PID is dead (a forked child of a killed run
    inherited it) is broken, with a warning. After locking, the file's inode is compared with
    the path's: a lock taken on a file another run has just unlinked is retried.
    """
    path = out.parent / f".{out.name}.lock"
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise OutputError(f"{out.parent}: cannot create a lock file in: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid = _read_pid(fd)
            if pid is not None and not pid_alive(pid):
                time.sleep(0.2)  # a live run may have locked but not yet written its PID
                if _read_pid(fd) == pid and _same(fd, path):
                    warnings.warn(f"{out}: broke the stale lock {path.name} of dead process {pid}", SensorlessWarning,
                                  stacklevel=3)
                    _unlink(path)
                    os.close(fd)
                    continue
            os.close(fd)
            who = f" (PID {pid})" if pid else ""
            raise OutputError(f"{out}: another sensorless run{who} is writing this output directory; wait for it "
                              "to finish or choose another output directory") from None
        if _same(fd, path):
            break
        os.close(fd)
    pid = _read_pid(fd)
    if pid is not None and pid != os.getpid() and not pid_alive(pid):
        warnings.warn(f"{out}: removed the stale lock {path.name} of killed process {pid}", SensorlessWarning,
                      stacklevel=3)
    with contextlib.suppress(OSError):  # the PID is information only (a full disk must not stop the run)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    try:
        yield
    finally:
        _unlink(path)
        os.close(fd)


def _same(fd: int, path: Path) -> bool:
    try:
        return os.fstat(fd).st_ino == os.stat(path).st_ino
    except FileNotFoundError:
        return False


def _unlink(p: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(p)


# ---- rename primitives ---------------------------------------------------------------------
def _renameat2_function():
    if not sys.platform.startswith("linux"):
        return None
    libc = ctypes.CDLL(None, use_errno=True)  # the process's symbols, libc's among them
    if not (hasattr(libc, "renameat2") or hasattr(libc, "syscall")):  # find_library runs ldconfig: a subprocess
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
    fn = getattr(libc, "renameat2", None)
    if fn is not None:
        fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        return fn
    nr = _SYSCALL.get(platform.machine())
    if nr is None:
        return None
    return lambda a, s, b, d, f: libc.syscall(ctypes.c_long(nr), ctypes.c_int(a), ctypes.c_char_p(s), ctypes.c_int(b),
                                              ctypes.c_char_p(d), ctypes.c_uint(f))


_RENAMEAT2 = _renameat2_function()


def renameat2(src: Path, dst: Path, flags: int) -> None:
    """``renameat2(AT_FDCWD, src, AT_FDCWD, dst, flags)``; OSError (ENOSYS where unavailable)."""
    if _RENAMEAT2 is None:
        raise OSError(errno.ENOSYS, os.strerror(errno.ENOSYS), str(src))
    if _RENAMEAT2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) != 0:
        e = ctypes.get_errno()
        raise OSError(e, os.strerror(e), str(src), None, str(dst))


def _journal(out: Path) -> Path:
    return out.parent / f".{out.name}.journal"


def _write_journal(journal: Path, text: str) -> None:
    """Write the journal atomically: a ``.NAME.PID-HEX.tmp`` sibling (removed by
    :func:`remove_dead_temps` if this process dies) renamed into place."""
    tmp = journal.parent / f".{journal.name}.{os.getpid()}-{secrets.token_hex(6)}.tmp"
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, journal)
    except OSError as exc:
        _unlink(tmp)
        raise OutputError(f"{journal}: cannot write: {exc.strerror or exc}") from None


def swap_in(tmp: Path, out: Path, token: str) -> Path | None:
    """Make the complete tree ``tmp`` become ``out``; return where the previous ``out`` now is
    (for the caller to remove), or None. ``out`` is complete at every instant."""
    if not out.exists():
        try:
            renameat2(tmp, out, RENAME_NOREPLACE)
        except OSError as exc:
            if exc.errno not in _UNSUPPORTED:
                raise
            os.rename(tmp, out)  # under the lock: nothing else creates out meanwhile
        return None
    try:
        renameat2(tmp, out, RENAME_EXCHANGE)
        return tmp
    except OSError as exc:
        if exc.errno not in _UNSUPPORTED:
            raise
    old = out.parent / f".{out.name}.old-{token}"
    journal = _journal(out)
    _write_journal(journal, json.dumps({"out": out.name, "old": old.name, "new": tmp.name, "pid": os.getpid()}))
    os.rename(out, old)
    try:
        os.rename(tmp, out)
    except BaseException:
        os.rename(old, out)
        _unlink(journal)
        raise
    _unlink(journal)
    return old


# ---- recovery ------------------------------------------------------------------------------
def recover_locked(out: Path) -> str | None:
    """With the lock on ``out`` held: finish or undo an interrupted swap, remove dead leftovers.

    When ``out`` is missing, the journaled previous output (else the newest complete
    ``.OUT.old-*``, else a complete journaled new tree) is renamed back to ``out``. Returns the
    name of the tree restored, or None.
    """
    prefix = f".{out.name}."
    try:
        names = [e.name for e in os.scandir(out.parent) if e.name.startswith(prefix)]
    except OSError:
        return None
    journal = _journal(out)
    planned: dict = {}
    if journal.name in names:
        try:
            planned = json.loads(journal.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            planned = {}
    restored = None
    if not out.exists() and not out.is_symlink():
        olds = sorted((out.parent / n for n in names if n.startswith(prefix + "old-")),
                      key=lambda p: p.stat().st_mtime if p.exists() else 0, reverse=True)
        candidates = [out.parent / str(planned["old"])] if isinstance(planned.get("old"), str) else []
        candidates += olds
        candidates += [out.parent / str(planned["new"])] if isinstance(planned.get("new"), str) else []
        for c in candidates:
            if c.name.startswith(prefix) and "/" not in c.name and is_complete(c):
                os.rename(c, out)
                restored = c.name
                warnings.warn(f"{out}: restored the output from {c.name} (a run replacing it was interrupted)",
                              SensorlessWarning, stacklevel=3)
                break
    for n in names:
        p = out.parent / n
        if n.startswith((prefix + "tmp-", prefix + "old-")) and n != restored:
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
        elif n.endswith(".tmp") and _dead_temp(n[len(prefix):-4]):
            _unlink(p)
    _unlink(journal)
    remove_dead_temps(journal)
    return restored


def _dead_temp(middle: str) -> bool:
    """``PID-HEX`` of an atomic-write temporary file whose process is gone."""
    pid, _, rest = middle.partition("-")
    return pid.isdigit() and bool(rest) and not pid_alive(int(pid))


def remove_dead_temps(path: Path) -> None:
    """Remove ``.NAME.PID-HEX.tmp`` files next to ``path`` left by dead processes."""
    prefix = f".{path.name}."
    with contextlib.suppress(OSError):
        for e in os.scandir(path.parent):
            if e.name.startswith(prefix) and e.name.endswith(".tmp") and _dead_temp(e.name[len(prefix):-4]):
                _unlink(path.parent / e.name)


def recover_output(out: str | os.PathLike) -> str | None:
    """Complete or undo an interrupted replacement of the output directory ``out``.

    Restores the previous output when a kill left ``out`` missing, removes hidden temporary
    trees, journals, atomic-write temporaries and the lock of dead runs. Returns the name of
    the hidden tree that was restored (a warning names it too), or None. Raises
    :class:`~sensorless.errors.OutputError` while another run is writing ``out``.
    """
    out = Path(out)
    if not out.parent.is_dir():
        return None
    with lock(out):
        return recover_locked(out)

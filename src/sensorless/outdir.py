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
SHA-256. Only complete trees are ever restored.

Only names this tool made are ever removed or renamed. Each run has a run id ``PID-HEX``
(:func:`run_id`); its trees are ``.OUT.tmp-ID``/``.OUT.old-ID`` (:func:`run_tree_id`), and a
leftover one of a dead process is removed under the lock only when it is a real directory that
carries the id (:data:`RUN_MARKER` inside a tree being written, ``"run"`` in its manifest) or
holds a sensorless manifest, or the journal names it. Atomic-write temporaries are
``.NAME.ID.tmp`` regular files. The lock, the journal and the marker are opened relative to
their directory with ``O_NOFOLLOW`` (a symlink planted under their name is refused, never
followed), the lock created with ``O_EXCL``.
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
import re
import secrets
import stat
import shutil
import sys
import time
import warnings
from pathlib import Path
from typing import Iterator

from .errors import OutputError, SensorlessWarning

MANIFEST = ".sensorless-output.json"
TOOL = "sensorless"
#: the file holding the run id inside a tree being written (removed before its manifest is written)
RUN_MARKER = ".sensorless-run"
_RUN_ID = re.compile(r"(\d+)-([0-9a-f]{12})")
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
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
    (symlinks are entries, never followed; a tree's own :data:`RUN_MARKER` is not listed)."""
    files, dirs = [], []
    for root, subdirs, names in os.walk(directory):
        rel = Path(root).relative_to(directory)
        files += [(rel / f).as_posix() for f in names if not (root == str(directory) and f == RUN_MARKER)]
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


def warn_if_edited(path: str | os.PathLike, what: str = "file") -> bool:
    """Warn (SensorlessWarning) when ``path`` lies in a sensorless output folder whose manifest records
    another SHA-256 for it: its values are not those the tool wrote (a tampered 150 kg link, friction
    1e6 or a scaler of 1e300 inside every range check). True when it warned."""
    path = Path(path)
    for folder in list(path.parents)[:3]:  # the output folder may hold it in a sub-folder (residual/model.json)
        doc = read_manifest(folder)
        rel = path.relative_to(folder).as_posix()
        if doc is not None and rel in doc.get("files", []):
            break
    else:
        return False
    want = (doc.get("hashes") or {}).get(rel) if isinstance(doc.get("hashes"), dict) else None
    if not isinstance(want, dict):
        return False
    try:
        same = digest(path) == {"size": want.get("size"), "sha256": want.get("sha256")}
    except OSError:
        return False
    if not same:
        warnings.warn(f"{path}: this {what} was changed since sensorless wrote it (its SHA-256 differs from "
                      f"{folder.name}/{MANIFEST}): its values are not the ones identified", SensorlessWarning,
                      stacklevel=3)
    return not same


def is_complete(directory: Path) -> bool:
    """A valid manifest, and every file it lists present with its recorded hash."""
    doc = read_manifest(directory)
    return doc is not None and directory.is_dir() and not directory.is_symlink() and \
        changed_file(directory, doc, missing_ok=False) is None


# ---- run ids and files opened without following links -----------------------------------
def run_id() -> str:
    """A new run id ``PID-HEX`` (12 hex digits): the names of this run's hidden trees and temporaries."""
    return f"{os.getpid()}-{secrets.token_hex(6)}"


def run_tree_id(out: Path, name: str, kinds: tuple[str, ...] = ("tmp", "old")) -> str | None:
    """The run id of ``name`` when it is ``.OUT.KIND-ID`` of ``out`` (KIND in ``kinds``); else None."""
    for kind in kinds:
        prefix = f".{out.name}.{kind}-"
        if name.startswith(prefix) and _RUN_ID.fullmatch(name[len(prefix):]):
            return name[len(prefix):]
    return None


def _pid_of(rid: str) -> int:
    return int(rid.partition("-")[0])


def open_nofollow(path: Path, flags: int = os.O_RDONLY, mode: int = 0o666, what: str = "file") -> int:
    """``openat(dir, name, flags | O_NOFOLLOW)``: a file descriptor of the regular file ``path``
    (symlinks in its directory part are the user's; its own name is never followed). OSError
    (ELOOP for a symlink), or OutputError for a FIFO, device, socket or directory there."""
    dfd = os.open(path.parent if str(path.parent) else ".", os.O_RDONLY | os.O_DIRECTORY | _CLOEXEC)
    try:
        fd = os.open(path.name, flags | _NOFOLLOW | _CLOEXEC | getattr(os, "O_NONBLOCK", 0), mode, dir_fd=dfd)
    finally:
        os.close(dfd)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OutputError(f"{path}: the {what} is not a regular file; refusing to use it (remove it yourself)")
    return fd


def read_nofollow(path: Path, limit: int = 1 << 16) -> str | None:
    """The text of the regular file ``path`` (at most ``limit`` bytes; never through a symlink), or None."""
    try:
        fd = open_nofollow(path)
    except (OSError, OutputError):
        return None
    try:
        return os.read(fd, limit).decode("utf-8", "replace")
    finally:
        os.close(fd)


def _symlink_refusal(out: Path, path: Path, what: str, exc: OSError) -> OutputError:
    if exc.errno == errno.ELOOP or path.is_symlink():
        return OutputError(f"{out}: {path.name} (the {what}) is a symbolic link; refusing to follow it (remove it "
                           "yourself)")
    return OutputError(f"{out.parent}: cannot create the {what} in: {exc.strerror or exc}")


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
        try:  # created with O_EXCL; an existing one (a dead run's) opened without following a link
            try:
                fd = open_nofollow(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, what="lock file")
            except FileExistsError:
                fd = open_nofollow(path, os.O_RDWR, what="lock file")
                text = os.pread(fd, 64, 0)
                if text.strip() and not text.strip().isdigit():  # not a PID: a file of the user's
                    os.close(fd)
                    raise OutputError(f"{out}: {path.name} exists and is not a sensorless lock file (it holds "
                                      "something other than a process id); refusing to use it (remove it yourself)")
        except FileNotFoundError:
            continue  # removed between the two opens: create it again
        except OSError as exc:
            raise _symlink_refusal(out, path, "lock file", exc) from None
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
        return os.fstat(fd).st_ino == os.lstat(path).st_ino
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
    """Write the journal atomically: a ``.NAME.ID.tmp`` sibling (created with O_EXCL, never through a
    link; removed by :func:`remove_dead_temps` if this process dies) renamed into place."""
    tmp = journal.parent / f".{journal.name}.{run_id()}.tmp"
    try:
        fd = open_nofollow(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, what="journal")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
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
            planned = json.loads(read_nofollow(journal) or "{}")
        except ValueError:
            planned = {}
        if not isinstance(planned, dict):
            planned = {}
    # the journal names only trees of this OUT (a plain name with a run id), never a path elsewhere
    journaled = {str(planned.get(k)) for k in ("old", "new") if isinstance(planned.get(k), str)
                 and run_tree_id(out, str(planned.get(k))) is not None}
    restored = None
    if not out.exists() and not out.is_symlink():
        olds = sorted((out.parent / n for n in names if run_tree_id(out, n, ("old",))),
                      key=lambda p: p.stat().st_mtime if p.exists() else 0, reverse=True)
        candidates = [out.parent / str(planned["old"])] if str(planned.get("old")) in journaled else []
        candidates += olds
        candidates += [out.parent / str(planned["new"])] if str(planned.get("new")) in journaled else []
        for c in candidates:
            if is_complete(c):
                os.rename(c, out)
                restored = c.name
                warnings.warn(f"{out}: restored the output from {c.name} (a run replacing it was interrupted)",
                              SensorlessWarning, stacklevel=3)
                break
    for n in names:
        p = out.parent / n
        rid = run_tree_id(out, n)
        if rid is not None and n != restored:
            if pid_alive(_pid_of(rid)):
                continue
            if _ours(p, rid, n in journaled):
                remove_tree(p)
            else:  # an empty one (a kill at the end of remove_tree) holds nothing to lose
                with contextlib.suppress(OSError):
                    os.rmdir(p)
        elif n.endswith(".tmp") and _dead_temp(n[len(prefix):-4]):
            _unlink_regular(p)
    if journaled and planned.get("out") == out.name:  # ours (a user's file, link or folder of that name stays)
        _unlink_regular(journal)
    remove_dead_temps(journal)
    return restored


def remove_tree(path: Path) -> None:
    """Remove a tree of this tool, its marks (:data:`RUN_MARKER`, :data:`MANIFEST`) last: a kill
    part way leaves a tree that is still recognisably ours."""
    with contextlib.suppress(OSError):
        for e in os.scandir(path):
            if e.name in (RUN_MARKER, MANIFEST):
                continue
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path, ignore_errors=True)
            else:
                _unlink(Path(e.path))
    for name in (MANIFEST, RUN_MARKER):
        _unlink(path / name)
    shutil.rmtree(path, ignore_errors=True)


def _ours(tree_path: Path, rid: str, journaled: bool) -> bool:
    """A real directory this tool wrote: the journal names it, its marker holds ``rid``, or it holds a
    sensorless manifest (a previous output moved aside, a finished tree not yet swapped in)."""
    try:
        if not stat.S_ISDIR(os.lstat(tree_path).st_mode):
            return False
    except OSError:
        return False
    if journaled:
        return True
    marker = read_nofollow(tree_path / RUN_MARKER, 64)
    if marker is not None and marker.strip() == rid:
        return True
    return read_manifest(tree_path) is not None


def _dead_temp(middle: str) -> bool:
    """A run id (:func:`run_id`) of an atomic-write temporary file whose process is gone."""
    return _RUN_ID.fullmatch(middle) is not None and not pid_alive(_pid_of(middle))


def _unlink_regular(p: Path) -> None:
    """Remove ``p`` when it is a regular file (never a directory, link target or special file)."""
    with contextlib.suppress(OSError):
        if stat.S_ISREG(os.lstat(p).st_mode):
            os.unlink(p)


def remove_dead_temps(path: Path) -> None:
    """Remove ``.NAME.ID.tmp`` regular files next to ``path`` left by dead processes."""
    prefix = f".{path.name}."
    with contextlib.suppress(OSError):
        for e in os.scandir(path.parent):
            if e.name.startswith(prefix) and e.name.endswith(".tmp") and _dead_temp(e.name[len(prefix):-4]):
                _unlink_regular(path.parent / e.name)


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

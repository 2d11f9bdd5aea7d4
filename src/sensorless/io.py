"""Safe output: files and directories appear whole or not at all, and only sensorless outputs are replaced.

* :func:`atomic_open` / :func:`atomic_write_text` / :func:`write_json_atomic` /
  :func:`write_npz_atomic` write ``path`` through a hidden sibling temporary file and
  ``os.replace`` it into place (readers see the old file or the new one, never half of one).
* :func:`atomic_output_dir` builds a whole output directory in a hidden sibling and renames
  it into place on success. Every directory it creates holds :data:`MANIFEST` (tool,
  version, command, time, files written). An existing directory is replaced only with
  ``force=True`` *and* when its manifest says sensorless wrote it and it holds nothing
  else; ``.``, ``..``, ``/``, the home directory, the working directory or any ancestor
  of it, and a directory holding an input file are never replaced. A lock file next to
  the output makes a concurrent run on the same path fail with a clear error instead of
  silently losing one result. SIGTERM (and SIGHUP) during the run removes the temporary
  directory before the process exits.
* Files and directories get the permissions of a normal ``open``/``mkdir``
  (``0o666``/``0o777`` minus the umask), not the ``0600``/``0700`` of ``tempfile``.
* JSON is strict: non-finite floats are written as ``null`` (``allow_nan=False``).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import fcntl
import json
import math
import os
import platform
import secrets
import shutil
import signal
import threading
from pathlib import Path
from typing import IO, Iterable, Iterator

import numpy as np

from .errors import InputError, OutputError

__all__ = [
    "MANIFEST",
    "atomic_open",
    "atomic_output_dir",
    "atomic_write_text",
    "check_input_file",
    "check_output_file",
    "jsonable",
    "read_json",
    "read_manifest",
    "versions",
    "write_json_atomic",
    "write_npz_atomic",
]

MANIFEST = ".sensorless-output.json"
TOOL = "sensorless"


# ---- version info -----------------------------------------------------------------------
def versions() -> dict:
    """Python and key package versions (for result files and manifests)."""
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("sensorless", "pin", "numpy", "scipy", "cvxpy", "clarabel"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


# ---- files -----------------------------------------------------------------------------
def _oserror(path: Path, exc: OSError, what: str = "cannot write") -> OutputError:
    return OutputError(f"{path}: {what}: {exc.strerror or exc}")


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a hidden sibling of ``path`` for writing; on success rename it to ``path``.

    ``mode`` is ``"w"`` (text) or ``"wb"``. The file is created with mode ``0o666``
    minus the umask. An exception inside the block removes the temporary file and
    leaves ``path`` untouched. ``path`` being a directory, or unwritable, raises
    :class:`~sensorless.errors.OutputError`.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open: mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _oserror(path.parent, exc, "cannot create directory") from None
    tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # kernel applies the umask
    except OSError as exc:
        raise _oserror(path, exc) from None
    try:
        with os.fdopen(fd, mode, **({"encoding": encoding} if "b" not in mode else {})) as fh:
            yield fh
        os.replace(tmp, path)
    except OSError as exc:
        _unlink(tmp)
        if isinstance(exc, IsADirectoryError) or exc.errno in (errno.EISDIR, errno.ENOTEMPTY, errno.EEXIST):
            raise OutputError(f"{path}: is a directory; give a file name") from None
        raise _oserror(path, exc) from None
    except BaseException:
        _unlink(tmp)
        raise


def _unlink(p: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(p)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)
    return Path(path)


def jsonable(x):
    """``x`` as plain JSON types: NumPy arrays/scalars converted, paths as strings, NaN/±inf as None."""
    if isinstance(x, dict):
        return {k if isinstance(k, str) else str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, set, frozenset)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.generic):
        return jsonable(x.item())
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, complex):
        raise TypeError(f"not JSON serialisable: complex value {x}")
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def write_json_atomic(obj: dict, path: str | os.PathLike) -> None:
    """Strict JSON (non-finite numbers as ``null``), written atomically."""
    text = json.dumps(jsonable(obj), indent=2, allow_nan=False)
    atomic_write_text(path, text + "\n")


def write_npz_atomic(path: str | os.PathLike, **arrays) -> Path:
    """``np.savez`` to exactly ``path`` (no ``.npz`` appended), atomically."""
    with atomic_open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return Path(path)


def _real(p: str | os.PathLike) -> Path:
    return Path(os.path.realpath(os.path.expanduser(os.fspath(p))))


def _inside(child: Path, parent: Path) -> bool:
    return child == parent or parent in child.parents


def check_output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Refuse an output file that is an existing directory or one of the ``inputs``."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; --out needs a file name (e.g. {path / 'out.npz'})")
    real = _real(path)
    for p in inputs:
        if p is not None and _real(p) == real:
            raise OutputError(f"{path}: is the input file {p}; refusing to overwrite it")
    return path


def check_input_file(path: str | os.PathLike, what: str = "input file") -> Path:
    """``path`` if it is an existing regular file (symlinks followed); else :class:`InputError`.

    FIFOs, devices and sockets are refused before anything opens them (opening a FIFO blocks
    until a writer appears; a device can be endless).
    """
    import stat

    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read this {what}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a directory; expected a {what}")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a regular file")
        raise InputError(f"{path}: is {kind}, not a regular file; refusing to read it as a {what}")
    return path


#: Largest JSON document :func:`read_json` parses by default (a model's result.json is < 1 MB).
MAX_JSON_BYTES = 64 * 1024 * 1024


def _no_constant(name: str):
    raise ValueError(f"'{name}' is not a JSON number")


def _unique_keys(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"key '{k[:60]}' appears twice")
        out[k] = v
    return out


def read_json(path: str | os.PathLike, what: str = "JSON file", max_bytes: int = MAX_JSON_BYTES,
              error: type[Exception] = InputError):
    """The strict JSON document in ``path``; ``error`` (one line naming the file) otherwise.

    Special files are refused before opening (:func:`check_input_file`), files over
    ``max_bytes`` before reading; NaN/Infinity and duplicate keys are not JSON here. The
    message never quotes the file's content (only the parser's position)."""
    path = check_input_file(path, what)
    try:
        size = os.stat(path).st_size
        if size > max_bytes:
            raise error(f"{path}: {what} of {size} bytes is larger than the limit of {max_bytes} bytes")
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read this {what}: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise error(f"{path}: {what} is larger than the limit of {max_bytes} bytes")
    try:
        return json.loads(raw.decode("utf-8-sig"), parse_constant=_no_constant, object_pairs_hook=_unique_keys)
    except UnicodeDecodeError:
        raise error(f"{path}: {what} is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") from None
    except ValueError as exc:
        raise error(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise error(f"{path}: {what} is nested too deeply") from None


# ---- output directories ---------------------------------------------------------------
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


def _files(directory: Path) -> list[str]:
    """Every non-directory entry below ``directory``, relative, sorted (symlinks not followed)."""
    out = []
    for root, dirs, files in os.walk(directory):
        rel = Path(root).relative_to(directory)
        out += [(rel / f).as_posix() for f in files]
        out += [(rel / d).as_posix() for d in dirs if (Path(root) / d).is_symlink()]
    return sorted(out)


def _refusal(out: Path, inputs: Iterable[str | os.PathLike]) -> str | None:
    """Why ``out`` must never be created or replaced, or None."""
    raw = os.fspath(out)
    if os.path.basename(raw.rstrip("/") or "/") in (".", ".."):
        return "'.' and '..' are never used as output directories"
    real = _real(out)
    if real == Path(real.anchor):
        return "it is the filesystem root"
    if real == _real(Path.home()):
        return "it is your home directory"
    cwd = _real(os.getcwd())
    if real == cwd:
        return "it is the current working directory"
    if real in cwd.parents:
        return "it contains the current working directory"
    for p in inputs:
        if p is not None and _inside(_real(p), real):
            return f"it contains the input {p}"
    if out.is_symlink():
        return "it is a symbolic link"
    if out.exists() and not out.is_dir():
        return "it exists and is not a directory"
    return None


def _check_replaceable(out: Path, force: bool, inputs) -> None:
    why = _refusal(out, inputs)
    if why:
        raise OutputError(f"{out}: refusing to write this output directory: {why}")
    if not out.exists():
        return
    if not force:
        raise OutputError(f"{out}: output directory exists; pass --force to replace it (a previous sensorless output only)")
    doc = read_manifest(out)
    if doc is None:
        raise OutputError(
            f"{out}: refusing to replace a directory sensorless did not create (no valid {MANIFEST}); "
            "choose a new --out or remove it yourself"
        )
    extra = sorted(set(_files(out)) - set(doc["files"]) - {MANIFEST})
    if extra:
        shown = ", ".join(extra[:3]) + (f" and {len(extra) - 3} more" if len(extra) > 3 else "")
        raise OutputError(f"{out}: refusing to replace it: it holds files sensorless did not write ({shown})")


@contextlib.contextmanager
def _lock(out: Path) -> Iterator[None]:
    """Exclusive, non-blocking ``flock`` on ``.<name>.lock`` next to ``out``; removed on exit.

    After locking, the file's inode is compared with the path's: a lock taken on a file
    another run has just unlinked is retried, so two runs never both hold the lock.
    """
    lock = out.parent / f".{out.name}.lock"
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise _oserror(out.parent, exc, "cannot create a lock file in") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputError(
                f"{out}: another sensorless run is writing this output directory; wait for it to finish "
                "or choose another --out"
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        _unlink(lock)
        os.close(fd)


@contextlib.contextmanager
def _terminate_as_exit() -> Iterator[None]:
    """In the main thread, turn SIGTERM/SIGHUP into ``SystemExit(128 + signum)`` so cleanup runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise SystemExit(128 + signum)

    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        old = signal.getsignal(sig)
        if old in (signal.SIG_DFL, None):  # never override a handler (or SIG_IGN) someone installed
            previous[sig] = old
            signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)


def _write_manifest(tmp: Path, command: dict | None) -> None:
    doc = {
        "tool": TOOL,
        "version": versions().get("sensorless"),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": command or {},
        "files": _files(tmp),
        "versions": versions(),
    }
    write_json_atomic(doc, tmp / MANIFEST)


@contextlib.contextmanager
def atomic_output_dir(
    out: str | os.PathLike,
    force: bool = False,
    *,
    inputs: Iterable[str | os.PathLike] = (),
    command: dict | None = None,
) -> Iterator[Path]:
    """Yield a hidden temporary directory; on success it becomes ``out`` (with a manifest).

    Refusals (:class:`~sensorless.errors.OutputError`, even with ``force``): ``.``/``..``,
    ``/``, home, the working directory or an ancestor, a directory holding one of
    ``inputs``, a symlink or a file, and an existing directory that is not a previous
    sensorless output (manifest) or holds files it did not write. Without ``force`` an
    existing ``out`` is never touched. On any exception (or SIGTERM) the temporary
    directory is removed and ``out`` is left as it was.
    """
    out = Path(out)
    inputs = [p for p in inputs if p is not None]
    _check_replaceable(out, force, inputs)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _oserror(out.parent, exc, "cannot create directory") from None
    with _lock(out), _terminate_as_exit():
        _check_replaceable(out, force, inputs)  # again, now that no other run can change it
        tmp = out.parent / f".{out.name}.tmp-{secrets.token_hex(6)}"
        try:
            os.mkdir(tmp, 0o777)  # the kernel applies the umask (mkdtemp would give 0700)
        except OSError as exc:
            raise _oserror(out.parent, exc, "cannot create the output directory in") from None
        try:
            yield tmp
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        # the swap below is not interrupted half-way (a pending SIGTERM is handled after it)
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM, signal.SIGHUP})
        try:
            _write_manifest(tmp, command)
            _check_replaceable(out, force, inputs)
            if out.exists():
                old = out.parent / f".{out.name}.old-{secrets.token_hex(6)}"
                os.rename(out, old)
                try:
                    os.rename(tmp, out)
                except BaseException:
                    os.rename(old, out)
                    raise
                shutil.rmtree(old, ignore_errors=True)  # a validated previous sensorless output
            else:
                os.rename(tmp, out)
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            raise _oserror(out, exc) from None
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)

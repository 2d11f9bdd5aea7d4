"""Safe output: files and directories appear whole or not at all, and only sensorless outputs are replaced.

* :func:`atomic_open` / :func:`atomic_write_text` / :func:`write_json_atomic` /
  :func:`write_npz_atomic` write ``path`` through a hidden sibling temporary file and
  ``os.replace`` it into place (readers see the old file or the new one, never half of one).
* :func:`atomic_output_dir` builds a whole output directory in a hidden sibling and renames
  it into place on success. Every directory it creates holds :data:`~sensorless.outdir.MANIFEST` (tool,
  version, command, time, files written with size and SHA-256). An existing directory is
  replaced only with ``force=True`` *and* when its manifest says sensorless wrote it, it holds
  nothing else and no listed file was edited; ``.``, ``..``, ``/``, the home directory, the working directory or any ancestor
  of it, and a directory holding an input file are never replaced. A lock file next to
  the output makes a concurrent run on the same path fail with a clear error instead of
  silently losing one result. SIGTERM (and SIGHUP) during the run removes the temporary
  directory before the process exits; the swap itself is kill-safe, even under SIGKILL
  (:mod:`sensorless.outdir`, :func:`~sensorless.outdir.recover_output`).
* Single output files (:func:`check_output_file`) never replace an existing file without
  ``force``, an input, a file inside an input folder, or a FIFO/device/socket.
* Files and directories get the permissions of a normal ``open``/``mkdir``
  (``0o666``/``0o777`` minus the umask), not the ``0600``/``0700`` of ``tempfile``.
* JSON is strict: non-finite floats are written as ``null`` (``allow_nan=False``).
"""

from __future__ import annotations

import contextlib
import functools
import datetime as _dt
import errno
import json
import math
import os
import platform
import shutil
import signal
import sys
import threading
from pathlib import Path
from typing import IO, Iterable, Iterator

import numpy as np

from . import outdir
from .outdir import MANIFEST, TOOL, read_manifest
from .errors import InputError, OutputError, setting

__all__ = [
    "atomic_open",
    "atomic_output_dir",
    "atomic_write_text",
    "check_input_file",
    "check_output_file",
    "jsonable",
    "read_json",
    "VERSIONED",
    "versions",
    "write_json_atomic",
    "write_npz_atomic",
]


# ---- version info -----------------------------------------------------------------------
#: (the record's key, the distribution, its import name) of the packages whose versions a result names
VERSIONED = (("sensorless", "sensorless", "sensorless"), ("pin", "pin", "pinocchio"), ("numpy", "numpy", "numpy"),
             ("scipy", "scipy", "scipy"), ("cvxpy", "cvxpy", "cvxpy"), ("clarabel", "clarabel", "clarabel"))


def versions() -> dict:
    """Python's version and those of the key packages (:data:`VERSIONED`) this process has loaded: a
    package not loaded had no part in the result (cvxpy when the LMI went to Clarabel directly). Each
    module's ``__version__``, else its distribution's metadata (``importlib.metadata`` reads every
    installed package's: ~30 ms, paid only then)."""
    out = {"python": platform.python_version()}
    for key, dist, module in VERSIONED:
        m = sys.modules.get(module)
        if m is None:
            continue
        v = getattr(m, "__version__", None)
        v = v if isinstance(v, str) else _dist_version(dist)
        if v is not None:
            out[key] = v
    return out


@functools.lru_cache(maxsize=None)
def _dist_version(dist: str) -> str | None:
    import importlib.metadata as md

    try:
        return md.version(dist)
    except md.PackageNotFoundError:
        return None


# ---- files -----------------------------------------------------------------------------
def _oserror(path: Path, exc: OSError, what: str = "cannot write") -> OutputError:
    return OutputError(f"{path}: {what}: {exc.strerror or exc}")


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a hidden sibling of ``path`` for writing; on success rename it to ``path``.

    ``mode`` is ``"w"`` (text) or ``"wb"``. The file is created with mode ``0o666``
    minus the umask. An exception inside the block removes the temporary file and
    leaves ``path`` untouched. ``path`` being a directory, a FIFO/device/socket, or
    unwritable (no space, read-only, permission) raises :class:`~sensorless.errors.OutputError`.
    The temporary file is ``.NAME.PID-HEX.tmp``; those of dead processes are removed.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open: mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    _refuse_non_file(path, "give a file name", "; refusing to replace it with a regular file")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _oserror(path.parent, exc, "cannot create directory") from None
    outdir.remove_dead_temps(path)
    tmp = path.parent / f".{path.name}.{outdir.run_id()}.tmp"
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


def _special_kind(path: str | os.PathLike, st_mode: int | None = None) -> str | None:
    """"a FIFO (named pipe)", "a socket", "a device" (or "not a regular file") for a special file; else None."""
    import stat

    if st_mode is None:
        try:
            st_mode = os.stat(path).st_mode
        except OSError:
            return None
    if stat.S_ISREG(st_mode) or stat.S_ISDIR(st_mode):
        return None
    return ("a FIFO (named pipe)" if stat.S_ISFIFO(st_mode) else "a socket" if stat.S_ISSOCK(st_mode)
            else "a device" if stat.S_ISCHR(st_mode) or stat.S_ISBLK(st_mode) else "not a regular file")


def _refuse_non_file(path: Path, directory: str, special: str) -> None:
    """OutputError when ``path`` is a directory (``"PATH: is a directory; " + directory``) or a special
    file (``"PATH: is KIND" + special``)."""
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; {directory}")
    kind = _special_kind(path)
    if kind:
        raise OutputError(f"{path}: is {kind}{special}")


def check_output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), force: bool = False) -> Path:
    """``path`` if a command may write this output file; else :class:`~sensorless.errors.OutputError`.

    Refused: an existing directory; a FIFO, device or socket; one of the ``inputs``; an existing
    file inside an input directory, or any path inside an input that is a sensorless output
    folder (or the one an input file lies in: ``--model run/result.json`` protects ``run/``);
    an existing file without ``force``.
    """
    path = Path(path)
    too_long = _name_too_long(path)
    if too_long:
        raise OutputError(f"{path}: cannot be an output file: {too_long}")
    _refuse_non_file(path, f"the output needs a file name (e.g. {path / 'out.npz'})",
                     ", not a regular file; refusing to write over it")
    real = _real(path)
    for p in inputs:
        if p is None:
            continue
        rp = _real(p)
        if rp == real:
            raise OutputError(f"{path}: is the input file {p}; refusing to overwrite it")
        folder = _input_folder(p)
        if folder is not None and _inside(real, folder) and ((folder / MANIFEST).is_file() or path.exists()):
            raise OutputError(f"{path}: lies inside the input folder {folder}; refusing to write into it "
                              "(choose an output outside it)")
    if (path.exists() or path.is_symlink()) and not force:
        raise OutputError(f"{path}: output file exists; replace it with {setting('force', True)}")
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
        kind = _special_kind(path, st.st_mode)
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
#: bytes a hidden temporary name adds to an output's name (``.NAME.tmp-PID-HEX12``, ``.NAME.PID-HEX12.tmp``)
_HIDDEN_EXTRA = 40


def _name_too_long(path: Path) -> str | None:
    """Why ``path``'s name cannot be an output (not UTF-8, or too long once hidden for the atomic write), or None."""
    try:
        os.fspath(path).encode("utf-8")
    except UnicodeEncodeError:
        return ("its name is not valid UTF-8 (results record their output's name as text); choose a name of "
                "printable characters")
    n = len(os.fsencode(path.name))
    limit = 255
    with contextlib.suppress(OSError, ValueError, AttributeError):
        limit = os.pathconf(path.parent if str(path.parent) and path.parent.exists() else ".", "PC_NAME_MAX")
    if n + _HIDDEN_EXTRA > limit:
        return (f"its name is {n} bytes long; at most {limit - _HIDDEN_EXTRA} (the file system allows {limit}, "
                "and the atomic write adds a hidden prefix and suffix)")
    return None


def _input_folder(p) -> Path | None:
    """The folder no output may go into because of the input ``p``: ``p`` itself when it is a directory,
    the sensorless output folder a file input lies in (``--model run/result.json`` protects ``run/``)."""
    if p is None:
        return None
    rp = _real(p)
    return rp if rp.is_dir() else rp.parent if (rp.parent / MANIFEST).is_file() else None


def _refusal(out: Path, inputs: Iterable[str | os.PathLike]) -> str | None:
    """Why ``out`` must never be created or replaced, or None."""
    raw = os.fspath(out)
    if os.path.basename(raw.rstrip("/") or "/") in (".", ".."):
        return "'.' and '..' are never used as output directories"
    too_long = _name_too_long(out)
    if too_long:
        return too_long
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
        folder = _input_folder(p)
        if folder is not None and _inside(real, folder):
            return f"it lies inside the input folder {folder} (choose an output outside it)"
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
        raise OutputError(f"{out}: output directory exists; replace it with {setting('force', True)} (a previous "
                          "sensorless output only)")
    doc = read_manifest(out)
    if doc is None:
        raise OutputError(
            f"{out}: refusing to replace a directory sensorless did not create (no valid {MANIFEST}); "
            "choose a new output directory or remove it yourself"
        )
    files, dirs = outdir.tree(out)
    listed = {str(f) for f in doc["files"]}
    extra = sorted(set(files) - listed - {MANIFEST})
    if extra:
        shown = ", ".join(extra[:3]) + (f" and {len(extra) - 3} more" if len(extra) > 3 else "")
        raise OutputError(f"{out}: refusing to replace it: it holds files sensorless did not write ({shown})")
    known = set(doc["dirs"]) if isinstance(doc.get("dirs"), list) else set()
    known |= {p.as_posix() for f in listed for p in Path(f).parents if p != Path(".")}
    extra = sorted(set(dirs) - known)
    if extra:
        raise OutputError(f"{out}: refusing to replace it: it holds the folder {extra[0]} sensorless did not make")
    edited = outdir.changed_file(out, doc, missing_ok=True)
    if edited is not None:
        raise OutputError(f"{out}: refusing to replace it: {edited} was changed since sensorless wrote it "
                          "(its SHA-256 differs from the manifest); move it away or choose another output directory")


@contextlib.contextmanager
def _terminate_as_exit() -> Iterator[list]:
    """In the main thread, turn SIGTERM/SIGHUP into ``SystemExit(128 + signum)`` so cleanup runs.

    Yields a list that receives the signal number: a C extension that polls for signals while it
    runs (Clarabel does, to stop on Ctrl-C) may swallow the exception and report a stopped solve,
    so :func:`atomic_output_dir` also checks the list before the swap and never swaps in a run
    that was asked to terminate."""
    received: list = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handler(signum, frame):
        received.append(signum)
        raise SystemExit(128 + signum)

    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        old = signal.getsignal(sig)
        if old in (signal.SIG_DFL, None):  # never override a handler (or SIG_IGN) someone installed
            previous[sig] = old
            signal.signal(sig, handler)
    try:
        yield received
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)


def _write_manifest(tmp: Path, command: dict | None, run: str | None = None) -> None:
    files, dirs = outdir.tree(tmp)
    doc = {
        "tool": TOOL,
        "run": run,
        "version": versions().get("sensorless"),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": command or {},
        "files": files,
        "dirs": dirs,
        "hashes": {f: outdir.digest(tmp / f) for f in files},
        "versions": versions(),
    }
    write_json_atomic(doc, tmp / MANIFEST)


_ENVIRONMENT = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG, errno.EIO)


def _environment_error(out: Path, tmp: Path, exc: BaseException) -> OutputError | None:
    """``exc`` from writing into ``tmp`` as an OutputError naming ``out`` (not the hidden tree), or None."""
    if isinstance(exc, OutputError):
        return OutputError(str(exc).replace(str(tmp), str(out)))
    if isinstance(exc, OSError) and exc.errno in _ENVIRONMENT:
        name = exc.filename if isinstance(exc.filename, str) else None
        where = name.replace(str(tmp), str(out)) if name else str(out)
        return OutputError(f"{where}: cannot write: {exc.strerror or exc}")
    return None


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
    sensorless output (manifest) or holds files or folders it did not write, or a listed file
    the user has since edited (SHA-256 in the manifest). Without ``force`` an existing ``out``
    is never touched. On any exception (or SIGTERM) the temporary directory is removed and
    ``out`` is left as it was; no space left, a read-only file system or a permission denied
    while writing are an OutputError naming ``out``. The swap is kill-safe (see
    :mod:`sensorless.outdir`): first the lock is taken and any interrupted swap of an earlier
    run is finished or undone (:func:`~sensorless.outdir.recover_output`).
    """
    out = Path(out)
    inputs = [p for p in inputs if p is not None]
    _check_replaceable(out, force, inputs)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _oserror(out.parent, exc, "cannot create directory") from None
    with outdir.lock(out), _terminate_as_exit() as terminated:
        outdir.recover_locked(out)
        _check_replaceable(out, force, inputs)  # again, now that no other run can change it
        token = outdir.run_id()
        tmp = out.parent / f".{out.name}.tmp-{token}"
        try:
            os.mkdir(tmp, 0o777)  # the kernel applies the umask (mkdtemp would give 0700)
            (tmp / outdir.RUN_MARKER).write_text(token + "\n")  # names it ours, should this run die
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            raise _oserror(out.parent, exc, "cannot create the output directory in") from None
        try:
            yield tmp
            if terminated:  # the exception was swallowed on the way (see _terminate_as_exit)
                raise SystemExit(128 + terminated[0])
        except BaseException as exc:
            outdir.remove_tree(tmp)
            err = _environment_error(out, tmp, exc)
            if err is None:
                raise
            raise err from None
        # the swap is one renameat2(RENAME_EXCHANGE): no instant without a complete OUT, whatever
        # thread a signal reaches; blocking SIGTERM here only keeps the journal fallback tidy
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM, signal.SIGHUP})
        try:
            _write_manifest(tmp, command, token)
            os.unlink(tmp / outdir.RUN_MARKER)  # after the manifest: the tree is always marked as ours
            _check_replaceable(out, force, inputs)
            previous = outdir.swap_in(tmp, out, token)
        except BaseException as exc:
            outdir.remove_tree(tmp)
            if isinstance(exc, OSError):
                raise (_environment_error(out, tmp, exc) or _oserror(out, exc)) from None
            if isinstance(exc, OutputError):
                raise _environment_error(out, tmp, exc) from None
            raise
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if previous is not None:
            outdir.remove_tree(previous)  # a validated previous sensorless output

"""Xacro expansion with consent, in a child process with time and memory limits.

A xacro file is a program: ``${...}`` expressions and ``$(eval ...)`` are Python that xacro
evaluates (with known escapes from its sandbox), and ``xacro:include`` / ``load_yaml`` read
any file. :func:`expand_xacro` therefore runs only when the caller consented (``--trust-xacro``,
``trust_xacro=True``), and then in a separate interpreter (``_xacro_worker.py``) with a
wall-time limit (``SENSORLESS_XACRO_TIMEOUT`` seconds, default 30) and, set by the child on
itself, an address-space limit (``SENSORLESS_XACRO_MEMORY_MB``, default 1024), a file-size
limit and a CPU-time limit. The URDF is cached per
content under ``$XDG_CACHE_HOME/sensorless/xacro``.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from .errors import RobotModelError, UntrustedModelError

__all__ = ["expand_xacro", "refuse_xacro", "xacro_limits"]

DEFAULT_TIMEOUT = 30.0
DEFAULT_MEMORY_MB = 1024


def refuse_xacro(path: Path, how: str = "set `trust_xacro=True`") -> None:
    """UntrustedModelError: the file can run code when expanded; how to expand it yourself.
    Nothing of the file is read."""
    raise UntrustedModelError(
        f"{path}: a xacro file can run code on this machine when it is expanded; read it, then expand it "
        f"yourself (xacro {path} > robot.urdf) and load the URDF, or {how} to expand it here "
        f"(in a subprocess with time and memory limits)")


def _limit(name: str, default: float) -> float:
    raw = os.environ.get(name)
    if raw is None or not raw.strip():
        return default
    try:
        value = float(raw)
    except ValueError:
        value = -1.0
    if not value > 0 or value != value or value == float("inf"):
        raise RobotModelError(f"{name}={raw!r}: expected a positive number")
    return value


def xacro_limits() -> tuple[float, int]:
    """(wall-time limit [s], memory limit [MiB]) from the environment, else the defaults."""
    return _limit("SENSORLESS_XACRO_TIMEOUT", DEFAULT_TIMEOUT), int(_limit("SENSORLESS_XACRO_MEMORY_MB",
                                                                          DEFAULT_MEMORY_MB))


def _run_worker(path: Path, timeout: float, memory_mb: int) -> str:
    worker = Path(__file__).with_name("_xacro_worker.py")
    with tempfile.TemporaryDirectory(prefix="sensorless-xacro-") as tmp:
        out = Path(tmp) / "robot.urdf"
        proc = subprocess.Popen([sys.executable, "-P", str(worker), str(path.resolve()), str(out),
                                 str(memory_mb), str(int(timeout) + 1)],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                start_new_session=True)
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            _kill(proc)
            raise RobotModelError(f"{path}: xacro expansion stopped after the {timeout:g} s time limit "
                                  "(SENSORLESS_XACRO_TIMEOUT raises it)") from None
        finally:
            _kill(proc)
        code = proc.returncode
        if code == 0 and out.is_file():
            return out.read_text(encoding="utf-8")
    text = err.decode("utf-8", "replace")
    if code == 4:
        raise RobotModelError(f"{path}: a xacro file needs the 'xacro' package (pip install xacro, or the "
                              f"'ros' extra), or expand it first: xacro {path} > robot.urdf")
    if code == 3 or "MemoryError" in text:
        raise RobotModelError(f"{path}: xacro expansion ran out of its {memory_mb} MiB memory limit "
                              "(SENSORLESS_XACRO_MEMORY_MB raises it)")
    if code in (-signal.SIGXCPU, -signal.SIGKILL):
        raise RobotModelError(f"{path}: xacro expansion stopped at its CPU-time limit ({int(timeout) + 1} s; "
                              "SENSORLESS_XACRO_TIMEOUT raises it)")
    detail = next((ln[12:] for ln in reversed(text.splitlines()) if ln.startswith("XACRO-ERROR ")), "")
    detail = detail or " ".join(text.split())[-300:] or f"exit status {code}"
    raise RobotModelError(f"{path}: xacro could not expand it ({detail}); expand it where its ROS packages are "
                          f"installed: xacro {path} > robot.urdf")


def _kill(proc: subprocess.Popen) -> None:
    """End the worker: SIGTERM first (it kills every descendant, those that left its process group with
    ``setsid`` too: :mod:`._xacro_worker`), then SIGKILL to its whole process group, and reap it."""
    if proc.poll() is None:
        try:
            proc.terminate()
            proc.wait(timeout=2.0)
        except (OSError, subprocess.TimeoutExpired):
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # whatever is left in its group
    except OSError:
        pass
    proc.wait()


def expand_xacro(path: Path, *, trusted: bool = False) -> Path:
    """The URDF a ``.xacro`` file expands to (its default arguments), written once per content to
    ``$XDG_CACHE_HOME/sensorless/xacro`` and returned. ``trusted`` must be True (the caller's
    consent): else :func:`refuse_xacro`. RobotModelError names the file and the limit on a
    timeout or memory-out, and says how to expand it by hand when xacro fails."""
    path = Path(path)
    if not trusted:
        refuse_xacro(path)
    from .io import atomic_write_text, check_input_file

    check_input_file(path, "xacro file")
    timeout, memory_mb = xacro_limits()
    xml = _run_worker(path, timeout, memory_mb)
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "sensorless" / "xacro"
    out = cache / f"{path.name.split('.')[0]}-{hashlib.sha256(xml.encode()).hexdigest()[:16]}.urdf"
    if not out.exists():
        cache.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out, xml)
    return out

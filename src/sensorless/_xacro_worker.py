"""Child process of :func:`sensorless.xacro_expand.expand_xacro`: expand one xacro file.

Run as ``python -P _xacro_worker.py FILE OUT MEMORY_MB CPU_S``: it first limits its own address
space, file size and CPU time (``resource.setrlimit``; in the child itself rather than in a
``preexec_fn``, which is unsafe in a threaded parent), then imports only the standard library
and ``xacro`` (never the ``sensorless`` package) and writes the expanded URDF to OUT. Exit codes: 0 done, 2 xacro failed (last stderr line
``XACRO-ERROR <detail>``), 3 out of memory, 4 xacro not installed.

A trusted file may start processes, and one that calls ``setsid`` leaves the worker's process
group. On Linux the worker is therefore a child subreaper (``prctl(PR_SET_CHILD_SUBREAPER)``: every
orphaned descendant is re-parented to it, none escapes to init), and before it exits (done,
failed, SIGTERM from the parent at its time limit, SIGXCPU at its CPU limit) it kills and reaps
every descendant it has.
"""

import sys


def main(argv: list) -> int:
    _subreaper()
    try:
        return _expand(argv)
    finally:
        _kill_descendants()


def _subreaper() -> None:
    """Become the child subreaper (Linux); SIGTERM and SIGXCPU end the worker through its cleanup."""
    import signal

    def stop(signum, frame):
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGXCPU, stop)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
        except (OSError, AttributeError):
            pass


def _descendants(root: int) -> list:
    """Every process below ``root`` (from /proc; empty where there is none)."""
    import os

    children: dict = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    for e in entries:
        if not e.isdigit():
            continue
        try:
            with open(f"/proc/{e}/stat", "rb") as fh:
                stat = fh.read().decode("ascii", "replace")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(e))
    out, todo = [], [root]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def _kill_descendants() -> None:
    """Kill and reap every descendant (orphans come back to this subreaper), until none is left."""
    import os
    import signal
    import time

    for _ in range(100):
        kids = _descendants(os.getpid())
        for pid in kids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        while True:
            try:
                if os.waitpid(-1, os.WNOHANG)[0] == 0:
                    break
            except ChildProcessError:
                break
        if not kids:
            return
        time.sleep(0.01)


def _expand(argv: list) -> int:
    src, out, memory_mb, cpu = argv[1], argv[2], int(argv[3]), int(argv[4])
    import resource

    mem = memory_mb * 1024 * 1024
    resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
    resource.setrlimit(resource.RLIMIT_FSIZE, (mem, mem))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    try:
        import xacro
    except ImportError:
        return 4
    try:
        xml = xacro.process_file(src).toprettyxml(indent="  ")
    except MemoryError:
        return 3
    except BaseException as exc:  # noqa: BLE001 - XacroException, SystemExit from its helpers, anything
        if _out_of_memory(exc):
            return 3
        try:
            detail = " ".join(str(exc).split())[:300] or type(exc).__name__
        except BaseException:  # noqa: BLE001 - str() itself may fail (e.g. int too large to print)
            detail = type(exc).__name__
        sys.stderr.write("\nXACRO-ERROR " + detail + "\n")
        return 2
    with open(out, "w", encoding="utf-8") as f:
        f.write(xml)
    return 0


def _out_of_memory(exc: BaseException) -> bool:
    """True if a MemoryError is in the chain (xacro wraps errors in XacroException.exc)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, MemoryError):
            return True
        seen.add(id(exc))
        exc = getattr(exc, "exc", None) or exc.__cause__ or exc.__context__
    return False


if __name__ == "__main__":
    sys.exit(main(sys.argv))

"""Wall time of a command as its user sees it: from the process start until a file it writes exists
(``sensorless identify``'s ``OUT/result.json`` appears when its output folder is renamed into place,
complete with its figures) and until it exits, with the CPU seconds it and the children it waited
for used."""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from pathlib import Path

__all__ = ["run_timed"]


def run_timed(argv: list[str], env: dict, result: Path | None = None, timeout: float = 600.0) -> dict:
    """Run ``argv``, polling every millisecond for ``result``: ``{"result_json", "exit", "cpu",
    "returncode", "stderr_tail", "timed_out"}`` (``result_json`` None when it never appeared; seconds
    from the start)."""
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=err)
        seen, timed_out = None, False
        while True:
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if seen is None and result is not None and result.exists():
                seen = time.perf_counter() - t0
            if time.perf_counter() - t0 > timeout:
                p.kill()
                timed_out = True
            time.sleep(0.001)
        t_exit = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen would warn it still runs
        if seen is None and result is not None and result.exists():
            seen = t_exit  # written in the last millisecond before the exit
        err.seek(0)
        tail = err.read().decode(errors="replace").strip().splitlines()[-6:]
    return {"result_json": seen, "exit": t_exit, "cpu": usage.ru_utime + usage.ru_stime,
            "returncode": p.returncode, "stderr_tail": tail, "timed_out": timed_out}

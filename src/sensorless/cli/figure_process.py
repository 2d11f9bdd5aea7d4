"""Figures drawn by a child process while the command writes its results.

A command that ends with figures (``identify``: torques.png, friction.png) starts
:class:`FigureProcess` first thing: the child (:mod:`sensorless.report.plot_process`) imports
matplotlib (~0.5 s) on the other core while this process reads logs and fits; once the model's
rows are known the command sends the figures' layouts (the child builds them meanwhile). The fit
done, the command sends the figure jobs (arrays computed here, written to the pipe by a thread: the
jobs outgrow the pipe's buffer, and the child reads them only once it has warmed up) and goes on
writing result.json; the child writes each PNG atomically into the command's output folder (still the hidden
temporary one: the folder appears complete or not at all), and :meth:`FigureProcess.wait`
returns once every PNG is written. If the child cannot start or fails, ``wait`` returns False
and the command draws the same figures itself (:func:`~sensorless.report.plot_process.draw_job`),
as it does when no core is idle (:func:`idle_core`).
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

__all__ = ["FigureProcess", "idle_core"]


def idle_core(samples: int = 5, spacing: float = 5e-4) -> bool:
    """A core is free for the figure process: fewer runnable tasks than cores (this one included;
    ``/proc/loadavg``) in any of ``samples`` reads ``spacing`` s apart, so that a task runnable for an
    instant (a shell, a poller) does not decide it; else the 1-min load average below cores − 1
    where there is no such count. On a busy machine the child only competes with the fit (and
    costs a Python start-up), so the command draws the figures itself. (The 1-min average would
    also count this command's own previous runs: a user running identify twice on an idle machine.)"""
    import time

    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    if cores < 2:
        return False
    try:
        for k in range(samples):
            with open("/proc/loadavg", encoding="ascii") as fh:
                if int(fh.read().split()[3].split("/")[0]) < cores:
                    return True
            if k + 1 < samples:
                time.sleep(spacing)
        return False
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.getloadavg()[0] < cores - 1
    except OSError:  # no load average on this platform
        return True


class FigureProcess:
    """A child Python that pre-imports matplotlib, then draws the jobs it is sent (once)."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen | None = None
        self._sent = False
        self._writer: threading.Thread | None = None
        self._write_error: BaseException | None = None
        self._err = None
        pkg_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([pkg_root, *([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])])
        env.setdefault("MPLBACKEND", "Agg")
        try:
            self._err = tempfile.TemporaryFile()  # a file, not a pipe: a chatty child never blocks
            self._proc = subprocess.Popen([sys.executable, "-m", "sensorless.report.plot_process"], env=env,
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err)
        except OSError:
            self._proc = None

    def prepare(self, layouts: list) -> None:
        """Send the figures' layouts (``(kind, (count, has_title), path)``, before the jobs): the child
        builds the empty figures while the command fits (:func:`~sensorless.report.plot_process.prepare_layouts`)."""
        if self._proc is None or self._sent:
            return
        try:
            from ..report.plot_process import frame

            self._proc.stdin.write(frame("layouts", layouts))
            self._proc.stdin.flush()
        except (OSError, ValueError, pickle.PicklingError):
            self.close()

    def submit(self, jobs: list) -> bool:
        """Send every job (once) without waiting for the child to read them (a thread writes them);
        False if the child is not running (the caller draws them itself)."""
        if self._proc is None or self._sent:
            return False
        self._sent = True
        try:
            from ..report.plot_process import frame

            data = frame("jobs", jobs)
        except (pickle.PicklingError, TypeError, AttributeError):
            self.close()
            return False
        self._writer = threading.Thread(target=self._write, args=(self._proc.stdin, data), name="figure-jobs",
                                        daemon=True)
        self._writer.start()
        return True

    def _write(self, stdin, data: bytes) -> None:
        """The writer thread: the jobs, then the end of the stream (the child's cue that no more come)."""
        try:
            stdin.write(data)
            stdin.close()
        except (OSError, ValueError) as exc:  # the child died, or close() ended it
            self._write_error = exc

    def wait(self, timeout: float | None = 600.0) -> bool:
        """True once the child has written every job's PNG; False if it failed (nothing half-written:
        each PNG is written atomically)."""
        if self._proc is None or not self._sent:
            return False
        if self._writer is not None:
            self._writer.join(timeout)
            if self._writer.is_alive() or self._write_error is not None:
                self.close()
                return False
        try:
            out = self._proc.stdout.read()  # "ok" once every PNG is written, at the child's exit
            self._proc.wait(timeout=timeout)
        except (OSError, ValueError, subprocess.TimeoutExpired):
            self.close()
            return False
        ok = self._proc.returncode == 0 and out.strip() == b"ok"
        self.close()
        return ok

    def close(self) -> None:
        """Stop the child if it is still running (an error in the parent, or figures not wanted). The
        child goes first: a write blocked on its full pipe then fails, and the writer thread ends."""
        p, self._proc = self._proc, None
        if p is None:
            return
        if p.poll() is None:
            p.kill()
        p.wait()
        w, self._writer = self._writer, None
        if w is not None:
            w.join()
        for f in (p.stdin, p.stdout, self._err):
            try:
                f.close()
            except (OSError, ValueError):
                pass

    def __enter__(self) -> "FigureProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

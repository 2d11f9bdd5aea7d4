"""Figures drawn in a child process, off a command's critical path.

A command that ends with figures (``identify``'s torques.png and friction.png) starts
:class:`PlotProcess` when it starts: the child imports matplotlib (~0.5 s) on the other core
while the parent reads logs and fits. When the fit is done the parent sends figure *jobs*
(plain arrays and strings, computed in the parent, no robot model) and goes on writing
result.json; the child draws and writes each PNG atomically into the parent's output folder
(still the hidden temporary one), and :meth:`PlotProcess.wait` returns when every PNG is
written. If the child cannot start or fails, :meth:`wait` returns False and the caller draws
in its own process (the same figures).

Jobs: ``("torques", kwargs, path)`` → :func:`~.plots.torque_figure`; ``("friction", panels,
path)`` → :func:`~.friction_plot.draw_friction`.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["PlotProcess", "draw_job"]


class PlotProcess:
    """A child Python that pre-imports matplotlib, then draws the jobs it is sent (once)."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen | None = None
        self._sent = False
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

    def submit(self, jobs: list) -> bool:
        """Send every job (once); False if the child is not running (the caller draws them itself)."""
        if self._proc is None or self._sent:
            return False
        self._sent = True
        try:
            self._proc.stdin.write(pickle.dumps(jobs, protocol=pickle.HIGHEST_PROTOCOL))
            self._proc.stdin.close()
        except (OSError, ValueError, pickle.PicklingError):
            self.close()
            return False
        return True

    def wait(self, timeout: float | None = 600.0) -> bool:
        """True once the child has written every job's PNG; False if it failed (nothing half-written:
        each PNG is written atomically)."""
        if self._proc is None or not self._sent:
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
        """Stop the child if it is still running (an error in the parent, or figures not wanted)."""
        p, self._proc = self._proc, None
        if p is None:
            return
        for f in (p.stdin, p.stdout, self._err):
            try:
                f.close()
            except (OSError, ValueError):
                pass
        if p.poll() is None:
            p.kill()
        p.wait()

    def __enter__(self) -> "PlotProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def draw_job(kind: str, kwargs: dict, path) -> Path:
    """Draw one job and write its PNG (atomically) to ``path``."""
    from .figure_kit import save_figure

    if kind == "torques":
        from .plots import torque_figure

        fig = torque_figure(**kwargs)
    elif kind == "friction":
        from .friction_plot import draw_friction

        fig = draw_friction(**kwargs)
    else:
        raise ValueError(f"unknown figure job '{kind}'")
    return save_figure(fig, path)


def _main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    from . import figure_kit, friction_plot, plots  # noqa: F401  (imported while the parent works)
    from matplotlib.backends import backend_agg  # noqa: F401
    from matplotlib import figure  # noqa: F401

    data = sys.stdin.buffer.read()
    if not data:  # the parent needed no figures (or stopped)
        return 0
    for kind, kwargs, path in pickle.loads(data):
        draw_job(kind, kwargs, path)
    sys.stdout.write("ok")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(_main())

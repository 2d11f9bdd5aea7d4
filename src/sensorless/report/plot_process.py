"""The child side of :class:`~sensorless.cli.figure_process.FigureProcess`: figures drawn off a
command's critical path.

``python -m sensorless.report.plot_process`` imports matplotlib, then reads a pickled list of
jobs on stdin, draws each and writes its PNG atomically, and prints ``ok``. A job is
``("torques", kwargs, path)`` → :func:`~.plots.plot_torques` or ``("friction", panels, path)``
→ :func:`~.friction_plot.plot_friction_panels`: plain arrays and strings computed by the parent (no
robot model, so the child never imports Pinocchio or the identification stack).
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

__all__ = ["draw_job"]


def draw_job(kind: str, kwargs: dict, path) -> Path:
    """Draw one job and write its PNG (atomically) to ``path``."""
    if kind == "torques":
        from .plots import plot_torques

        kw = dict(kwargs)
        plot_torques(kw.pop("t"), kw.pop("measured"), kw.pop("predictions"), kw.pop("rows"), path, **kw)
    elif kind == "friction":
        from .friction_plot import plot_friction_panels

        plot_friction_panels(kwargs, path)
    else:
        raise ValueError(f"unknown figure job '{kind}'")
    return Path(path)


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

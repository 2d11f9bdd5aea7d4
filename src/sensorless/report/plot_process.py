"""The child side of :class:`~sensorless.cli.figure_process.FigureProcess`: figures drawn off a
command's critical path.

``python -m sensorless.report.plot_process`` imports matplotlib and draws a tiny figure of each
kind into memory (:func:`warm_up`: fonts, glyph caches, the artists' property tables and the
drawing code paths, ~0.4 s that a cold first figure would otherwise add after the fit). It then
reads messages on stdin (:func:`frame`):

* **the figures' layouts**, when the parent knows them before the fit ends (``identify`` does): the
  child forks once (:func:`_split`; the copy shares everything imported and warmed) and each of the
  two processes builds half the empty figures and draws them once (:func:`prepare_layouts`: axes,
  ticks and labels, ~40 % of a figure), side by side while the command fits; a process stops
  building when its jobs are already waiting. The jobs then go to the process that built their
  figure, which adds the data, draws and writes the PNG (0.3 s for a 12-axes figure instead of
  0.45 s afresh);
* **the jobs** without layouts before them: with several jobs it forks once and the two processes
  draw half the jobs each (:func:`draw_jobs`).

Building both figures during the fit, one per process after the warm-up, took 0.12 s off
``identify``'s median on the 2-core benchmark machine (alternating runs); building them without the
warm-up, or forking before it, was slower (a cold figure costs ~0.45 s more, and three busy
processes on two cores delay the fit). Each PNG is written atomically; ``ok`` is printed once all
are. A job is ``("torques", kwargs, path)`` →
:func:`~.plots.plot_torques` or ``("friction", panels, path)`` →
:func:`~.friction_plot.plot_friction_panels`: plain arrays and strings computed by the parent (no
robot model, so the child never imports Pinocchio or the identification stack).
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path

__all__ = ["draw_job", "draw_jobs", "frame", "job_layout", "prepare_layouts", "warm_up"]


def draw_job(kind: str, kwargs: dict, path, prepared: dict | None = None) -> Path:
    """Draw one job and write its PNG (atomically) to ``path``; into the figure ``prepared`` holds for
    it (:func:`prepare_layouts`) when that figure has the job's layout."""
    axes = None
    if prepared is not None and (kind, job_layout(kind, kwargs)) == prepared.get(str(path), (None, None))[:2]:
        axes = prepared[str(path)][2]
    if kind == "torques":
        from .plots import plot_torques

        kw = dict(kwargs)
        plot_torques(kw.pop("t"), kw.pop("measured"), kw.pop("predictions"), kw.pop("rows"), path, axes=axes, **kw)
    elif kind == "friction":
        from .friction_plot import plot_friction_panels

        plot_friction_panels(kwargs, path, axes=axes)
    else:
        raise ValueError(f"unknown figure job '{kind}'")
    return Path(path)


def job_layout(kind: str, kwargs: dict) -> tuple:
    """What a job's empty figure depends on: (row or joint count, has a title)."""
    n = len(kwargs.get("rows", ())) if kind == "torques" else len(kwargs.get("labels", ()))
    return n, bool(kwargs.get("title"))


def prepare_layouts(layouts: list, stop=lambda: False) -> dict:
    """The empty figures of ``layouts`` (``(kind, (count, has_title), path)``, as :func:`job_layout` and
    the jobs to come), each drawn once: the axes, their ticks and labels are built before the data
    arrive, and a job then only adds its artists. ``{path: (kind, layout, (fig, pairs))}``. Before
    each figure ``stop()`` may end the preparation (the jobs have arrived: drawing them afresh, in two
    processes, is then sooner than preparing the rest here)."""
    from .friction_plot import friction_axes
    from .plots import torque_axes

    out = {}
    for kind, layout, path in layouts:
        make = {"torques": torque_axes, "friction": friction_axes}.get(kind)
        if make is None:
            continue
        if stop():
            break
        fig, pairs = make(*layout)
        fig.canvas.draw()
        out[str(path)] = (kind, tuple(layout), (fig, pairs))
    return out


def frame(what: str, items: list) -> bytes:
    """A message to the figure process: its length (8 bytes, little-endian) and the pickled
    ``(what, items)``; ``what`` is ``"layouts"`` or ``"jobs"``."""
    data = pickle.dumps((what, items), protocol=pickle.HIGHEST_PROTOCOL)
    return len(data).to_bytes(8, "little") + data


def _read_exactly(fd: int, n: int) -> bytes | None:
    parts, got = [], 0
    while got < n:
        b = os.read(fd, n - got)
        if not b:
            return None
        parts.append(b)
        got += len(b)
    return b"".join(parts)


def _read_frame(fd: int):
    """The next :func:`frame` on ``fd`` (read unbuffered, so that :func:`_pending` sees what is left), or
    None at the end of the stream."""
    head = _read_exactly(fd, 8)
    body = None if head is None else _read_exactly(fd, int.from_bytes(head, "little"))
    return None if body is None else pickle.loads(body)


def _pending(fd: int) -> bool:
    """Something (the jobs, or the end of the stream) is waiting on ``fd``."""
    import select

    try:
        return bool(select.select([fd], [], [], 0)[0])
    except (OSError, ValueError):  # no select on this platform for pipes: never stop early
        return False


def warm_up() -> None:
    """Draw one small figure of each kind into memory: what the first real figure would pay once
    (font files, glyph layout, the Agg and PNG code paths) is paid before the jobs arrive."""
    import io

    import numpy as np

    from .figure_kit import DPI
    from .friction_plot import draw_friction
    from .plots import torque_figure

    y = np.sin(np.linspace(0.0, 1.0, 50))[:, None]
    for fig in (torque_figure(y[:, 0], y, {"A": y, "B": y}, ["j"], units=["N·m"], title="τ"),
                draw_friction(y, y, y, y, y, [("j: fv", "N·m", "rad/s")], title="τ")):
        fig.savefig(io.BytesIO(), format="png", dpi=DPI, pil_kwargs={"compress_level": 3})


def draw_jobs(jobs: list, fork: bool | None = None, prepared: dict | None = None) -> None:
    """Draw every job; with ``fork`` (default: several jobs, ``os.fork`` available and this process
    single-threaded, as the figure process is) a forked copy draws every other job meanwhile. A job
    the copy fails to draw is drawn here after it."""
    import threading

    jobs = list(jobs)
    if fork is None:
        fork = len(jobs) > 1 and hasattr(os, "fork") and threading.active_count() == 1
    theirs, mine = (jobs[1::2], jobs[0::2]) if fork else ([], jobs)
    pid = _fork() if theirs else None
    if pid == 0:  # the copy: its jobs, then gone without running the parent's exit handlers
        code = 1
        try:
            for job in theirs:
                draw_job(*job, prepared=prepared)
            code = 0
        finally:
            os._exit(code)
    for job in mine + (theirs if pid is None else []):
        draw_job(*job, prepared=prepared)
    if pid is not None:
        _, status = os.waitpid(pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            for job in theirs:  # each PNG is written atomically: a failed copy left none half-written
                draw_job(*job)


def _fork() -> int | None:
    try:
        sys.stdout.flush()
        return os.fork()
    except OSError:  # no memory or process slot: draw them all here
        return None


def _split(layouts: list):
    """Fork into two processes that each prepare every other layout (module docstring). The copy
    prepares its half, waits for its jobs on a private pipe, draws them and exits (status 0 when all
    were written); this process gets ``(its layouts, copy's pid, the pipe's write end, the copy's
    paths)``, or ``(layouts, None, None, set())`` where there is no fork or only one layout."""
    import threading

    if len(layouts) < 2 or not hasattr(os, "fork") or threading.active_count() != 1:
        return layouts, None, None, set()
    mine, theirs = layouts[0::2], layouts[1::2]
    r, w = os.pipe()
    pid = _fork()
    if pid is None:
        os.close(r)
        os.close(w)
        return layouts, None, None, set()
    if pid == 0:  # the copy: its figures, then its jobs; gone without the parent's exit handlers
        code = 1
        try:
            os.close(w)
            prepared = prepare_layouts(theirs, stop=lambda: _pending(r))
            msg = _read_frame(r)
            for job in (msg[1] if msg else []):
                draw_job(*job, prepared=prepared)
            code = 0
        finally:
            os._exit(code)
    os.close(r)
    return mine, pid, w, {str(p) for _, _, p in theirs}


def _main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    warm_up()
    fd = sys.stdin.fileno()
    prepared: dict = {}
    copy, pipe, theirs = None, None, set()
    while True:  # ("layouts", [...]) first when the parent knows them early, then ("jobs", [...])
        msg = _read_frame(fd)
        if msg is None:  # the parent needed no figures (or stopped)
            if pipe is not None:
                os.close(pipe)
                os.waitpid(copy, 0)
            return 0
        what, items = msg
        if what == "layouts" and copy is None:
            mine, copy, pipe, theirs = _split(items)
            prepared = prepare_layouts(mine, stop=lambda: _pending(fd))
        elif what == "jobs":
            break
    if copy is None:
        draw_jobs(items, prepared=prepared)
    else:
        sent = [j for j in items if str(j[2]) in theirs]
        try:
            with os.fdopen(pipe, "wb") as fh:
                fh.write(frame("jobs", sent))
        except OSError:  # the copy is gone: its jobs are drawn here below
            pass
        for job in items:
            if str(job[2]) not in theirs:
                draw_job(*job, prepared=prepared)
        _, status = os.waitpid(copy, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            for job in sent:  # each PNG is written atomically: a failed copy left none half-written
                draw_job(*job)
    sys.stdout.write("ok")
    sys.stdout.flush()
    os._exit(0)  # every PNG is written and closed: skip the interpreter's teardown (~0.1 s with matplotlib loaded)


if __name__ == "__main__":
    sys.exit(_main())

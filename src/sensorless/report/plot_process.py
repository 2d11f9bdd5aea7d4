"""The child side of :class:`~sensorless.cli.figure_process.FigureProcess`: figures drawn off a
command's critical path.

``python -m sensorless.report.plot_process`` imports matplotlib and draws a tiny figure of each
kind into memory (:func:`warm_up`: fonts, glyph caches and the drawing code paths are loaded then,
~0.3 s that would otherwise follow the fit). It then reads messages on stdin (:func:`frame`): the
figures' layouts, when the parent knows them before the fit ends, then the jobs. With at least
:data:`PREPARE_MIN_CORES` cores it builds each layout's empty figure and draws it once meanwhile
(:func:`prepare_layouts`: axes, ticks and labels cost ~40 % of a figure; it stops when the jobs
arrive first). With fewer it does not: on two cores that work competed with the fit (whose γ
cross-validation solves on two threads) and ``identify`` took 0.2 s longer (1.66 s against 1.47 s,
means of 8 alternating runs on the UR5 hard case), since the figure not yet built bounds the wait
anyway. It draws each job and writes its PNG atomically, and prints ``ok``. With several jobs it
forks once (the copy shares everything already imported and warmed) and the two processes draw
half the jobs each, on the two cores the waiting command leaves free. A job is ``("torques", kwargs, path)`` →
:func:`~.plots.plot_torques` or ``("friction", panels, path)`` →
:func:`~.friction_plot.plot_friction_panels`: plain arrays and strings computed by the parent (no
robot model, so the child never imports Pinocchio or the identification stack).
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path

__all__ = ["PREPARE_MIN_CORES", "draw_job", "draw_jobs", "frame", "job_layout", "prepare_layouts", "warm_up"]

PREPARE_MIN_CORES = 3  # the layouts are built during the fit only with a core beyond the fit's two


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
    from .figure_kit import text_style
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
        with text_style():
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


class _Inbox:
    """The parent's messages on ``fd``, read as whole frames as they arrive."""

    def __init__(self, fd: int) -> None:
        self.fd, self.queue, self.complete = fd, [], False

    def _take(self):
        msg = _read_frame(self.fd)
        self.complete = msg is None or msg[0] == "jobs"  # nothing comes after the jobs
        return msg

    def jobs_in(self) -> bool:
        """Read what is waiting; True once the jobs (or the end of the stream) are in."""
        while not self.complete and _pending(self.fd):
            self.queue.append(self._take())
        return self.complete

    def next(self):
        """The next message (waiting for it), or None at the end of the stream."""
        if self.queue:
            return self.queue.pop(0)
        return None if self.complete else self._take()


def warm_up(stop=lambda: False) -> None:
    """Draw one small figure of each kind into memory: what the first real figure would pay once
    (font files, glyph layout, the Agg and PNG code paths) is paid before the jobs arrive. The first
    (~0.3 s: most of it is shared by every kind) is always drawn; ``stop()`` true after it (the jobs
    are in) skips the others (~0.07 s each), which the forked copy drawing that kind then pays meanwhile."""
    import io

    import numpy as np

    from .figure_kit import render_png
    from .friction_plot import draw_friction
    from .plots import torque_figure

    y = np.sin(np.linspace(0.0, 1.0, 50))[:, None]
    kinds = (lambda: torque_figure(y[:, 0], y, {"A": y, "B": y}, ["j"], units=["N·m"], title="τ"),
             lambda: draw_friction(y, y, y, y, y, [("j: fv", "N·m", "rad/s")], title="τ"))
    for k, make in enumerate(kinds):
        if k and stop():
            break
        render_png(make(), io.BytesIO())


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


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _skip_set_docstrings() -> None:
    """As its modules load, matplotlib gives each Artist class a ``set`` whose signature lists the
    class's properties (every ``set_*`` method inspected) and whose docstring tabulates them (from every
    setter's docstring): ~0.12 s of this process's start, for help no one reads here. Only this process
    does without: each class still gets its ``set(**kwargs)``, the same call (aliases included; matplotlib
    never reads the signature when drawing), flagged as matplotlib's subclasses expect."""
    import matplotlib.artist

    def flag_only(cls) -> None:
        cls.set._autogenerated_signature = True  # what a subclass checks before giving itself a set

    matplotlib.artist.kwdoc = lambda artist: ""  # also used by docstring interpolation
    matplotlib.artist.Artist._update_set_signature_and_docstring = classmethod(flag_only)


def _main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    _skip_set_docstrings()
    inbox = _Inbox(sys.stdin.fileno())
    warm_up(stop=inbox.jobs_in)
    prepared: dict = {}
    while True:  # ("layouts", [...]) first when the parent knows them early, then ("jobs", [...])
        msg = inbox.next()
        if msg is None:  # the parent needed no figures (or stopped)
            return 0
        what, items = msg
        if what == "layouts" and _cores() >= PREPARE_MIN_CORES:
            prepared = prepare_layouts(items, stop=inbox.jobs_in)
        elif what == "jobs":
            break
    draw_jobs(items, prepared=prepared)
    sys.stdout.write("ok")
    sys.stdout.flush()
    os._exit(0)  # every PNG is written and closed: skip the interpreter's teardown (~0.1 s with matplotlib loaded)


if __name__ == "__main__":
    sys.exit(_main())

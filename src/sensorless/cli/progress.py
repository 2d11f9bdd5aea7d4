"""Progress bars on stderr for a command's long steps (rich), silent unless stderr is a terminal.

The library takes plain callbacks (``progress(n)``: n more samples folded; ``progress(done, total)``:
steps done so far); a command opens :func:`progress_bars` and hands each step a :class:`Step`'s
``advance`` or ``update``. Bars are drawn only when the console is a terminal and the environment
variable ``SENSORLESS_PROGRESS`` is not ``0`` (``off``/``false``/``no``); they are transient, so
nothing is left behind on the terminal, and pipes, files and CI logs get no bar at all.
"""

from __future__ import annotations

import contextlib
import os
from typing import Callable, Iterator, Optional

__all__ = ["PROGRESS_ENV", "Step", "progress_bars", "progress_enabled"]

PROGRESS_ENV = "SENSORLESS_PROGRESS"
_OFF = ("0", "off", "false", "no")

#: the console the bars are drawn on; None: the commands' stderr console (tests set a forced terminal)
console = None


def _console():
    if console is not None:
        return console
    from .console import err_console

    return err_console


def progress_enabled(target=None) -> bool:
    """True when bars are drawn on ``target`` (default: the stderr console): a terminal, and
    ``SENSORLESS_PROGRESS`` is not 0/off/false/no."""
    if os.environ.get(PROGRESS_ENV, "").strip().lower() in _OFF:
        return False
    target = _console() if target is None else target
    return bool(target.is_terminal) and not target.is_dumb_terminal


class Step:
    """One bar (a rich task); every method is a no-op when bars are off."""

    def __init__(self, bar=None, task=None) -> None:
        self._bar, self._task = bar, task

    def advance(self, n: float = 1) -> None:
        """``n`` more units done (the ``progress(n)`` callbacks of compression)."""
        if self._bar is not None:
            self._bar.advance(self._task, n)

    def update(self, done: float, total: Optional[float] = None, note: Optional[str] = None) -> None:
        """``done`` units so far, of ``total`` when given (the ``progress(done, total)`` callbacks);
        ``note``: text shown after the counts (e.g. the current objective)."""
        if self._bar is not None:
            self._bar.update(self._task, completed=done, **({} if total is None else {"total": total}),
                             **({} if note is None else {"note": note}))


class _Bars:
    def __init__(self, bar) -> None:
        self._bar = bar

    def step(self, description: str, total: Optional[float] = None) -> Step:
        """A new bar; ``total`` None: a pulsing bar until :meth:`Step.update` gives one."""
        if self._bar is None:
            return Step()
        return Step(self._bar, self._bar.add_task(description, total=total, note=""))

    def callback(self, description: str) -> Optional[Callable[..., None]]:
        """A ``progress(done, total)`` callback whose bar appears at its first call (a step that may
        not run, such as the cross-validation of ``--gamma auto``); None when bars are off."""
        if self._bar is None:
            return None
        step: list[Step] = []

        def update(done: float, total: Optional[float] = None) -> None:
            if not step:
                step.append(self.step(description, total))
            step[0].update(done, total)

        return update

    def close(self) -> None:
        """Stop drawing (before the command prints its results); idempotent."""
        if self._bar is not None:
            self._bar.stop()


@contextlib.contextmanager
def progress_bars(enabled: Optional[bool] = None) -> Iterator[_Bars]:
    """``with progress_bars() as bars: s = bars.step("reading logs", total=n); ...; s.advance()``.

    ``enabled`` None: :func:`progress_enabled`. When off, no rich Progress is built at all."""
    target = _console()
    if not (progress_enabled(target) if enabled is None else enabled):
        yield _Bars(None)
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   TextColumn("{task.fields[note]}"), console=target, transient=True)
    with bar:
        yield _Bars(bar)

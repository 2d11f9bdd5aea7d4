"""The CLI's rich consoles (stdout and stderr)."""

from __future__ import annotations

import os

from rich.console import Console

__all__ = ["console", "err_console"]


def _console(stderr: bool) -> Console:
    """Output that is not a terminal (a file, a pipe, CI) gets 200 columns unless COLUMNS says
    otherwise, so tables are not cut at rich's default of 80."""
    c = Console(stderr=stderr)
    if not c.is_terminal and not os.environ.get("COLUMNS"):
        c.width = 200
    return c


console = _console(False)
err_console = _console(True)

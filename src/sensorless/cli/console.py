"""The CLI's rich consoles (stdout and stderr), safe for names that come from users' files.

Joint, column and file names reach the console inside messages and tables. The consoles here
(:class:`SafeConsole`) strip control characters (terminal escape sequences, bells, carriage returns:
:func:`strip_control`) from every string they render, and a string whose markup does not parse
(a joint named ``a[/]b``) is printed as plain text instead of raising. :func:`safe` escapes a
user-supplied string for an f-string that also carries markup.
"""

from __future__ import annotations

import os
import re

from rich.console import Console
from rich.errors import MarkupError
from rich.markup import escape

__all__ = ["SafeConsole", "console", "err_console", "safe", "strip_control"]

#: C0 controls but tab and newline, DEL, and the C1 controls (ESC starts every terminal escape sequence)
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def strip_control(text: str) -> str:
    """``text`` without control characters (tab and newline kept)."""
    return _CONTROL.sub("", text)


def safe(text: object) -> str:
    """A user-supplied string for a rich message: control characters stripped, markup escaped."""
    return escape(strip_control(str(text)))


class SafeConsole(Console):
    """A rich Console that strips control characters and prints unparsable markup as plain text."""

    def render_str(self, text: str, **kwargs):
        text = strip_control(text)
        try:
            return super().render_str(text, **kwargs)
        except MarkupError:
            return super().render_str(text, **{**kwargs, "markup": False})


def _console(stderr: bool) -> Console:
    """Output that is not a terminal (a file, a pipe, CI) gets 200 columns unless COLUMNS says
    otherwise, so tables are not cut at rich's default of 80."""
    c = SafeConsole(stderr=stderr)
    if not c.is_terminal and not os.environ.get("COLUMNS"):
        c.width = 200
    return c


console = _console(False)
err_console = _console(True)

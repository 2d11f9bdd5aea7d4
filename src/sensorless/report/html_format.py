"""Cell formatting shared by the report.html sections: escaping, numbers, percent."""

from __future__ import annotations

import html
import math
from typing import Any

__all__ = ["esc", "num", "pct", "is_number"]


def esc(x: Any) -> str:
    """``x`` as HTML text (every value of a result document passes through here)."""
    return html.escape(str(x))


def is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def num(x: Any, digits: int = 4) -> str:
    """A number to ``digits`` significant digits; ``None`` as an em dash; text escaped."""
    if x is None:
        return "—"
    if is_number(x):
        if isinstance(x, float) and not math.isfinite(x):
            return "∞" if x > 0 else "−∞" if x < 0 else "—"
        return f"{x:.{digits}g}"
    return esc(x)


def pct(x: Any) -> str:
    """A fraction as percent with two decimals (``0.0103`` → ``1.03``), as the CLI's tables show it;
    below 0.01 % as ``<0.01``."""
    if not is_number(x) or (isinstance(x, float) and not math.isfinite(x)):
        return "—" if x is None or not is_number(x) else "∞"
    v = 100.0 * x
    if v != 0 and abs(v) < 0.005:
        return "&lt;0.01" if v > 0 else "&gt;−0.01"
    return f"{v:.2f}"

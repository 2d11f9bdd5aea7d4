"""CSV and whitespace-separated text tables (``.csv .txt .dat .log``; :mod:`..tabular`)."""

from __future__ import annotations

from pathlib import Path

from ..limits import prescan_text
from ..tabular import read_text_table
from .base import LogFormat

__all__ = ["TEXT"]


def _table(path: Path):
    """The table and whether it has a header; line length, field count and size bounded before pandas."""
    prescan_text(path, str(path))
    return read_text_table(path)


TEXT = LogFormat("text", ".csv/.txt/.dat/.log text", suffixes=(".csv", ".txt", ".dat", ".log"), table=_table)

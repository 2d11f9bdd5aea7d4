"""CSV and whitespace-separated text tables (``.csv .txt .dat .log``; :mod:`..tabular`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..limits import prescan_text
from ..names import RawLog
from ..tabular import fields_from_frame, read_text_table

__all__ = ["TextTable"]


@dataclass(frozen=True)
class TextTable:
    name = "text"
    suffixes = (".csv", ".txt", ".dat", ".log")
    description = ".csv/.txt/.dat/.log text"
    items = "columns"
    arrays = False
    trajectory = False

    def sniff(self, path: Path) -> bool:
        return path.suffix.lower() in self.suffixes

    def read(self, path: Path, columns, joint_names) -> RawLog:
        src = str(path)
        prescan_text(path, src)  # line length, field count and size bounded before pandas
        df, header = read_text_table(path)
        return fields_from_frame(df, src, columns, joint_names, header)

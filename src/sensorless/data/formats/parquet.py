"""Apache Parquet tables (``.parquet .pq``; :func:`..tabular.read_parquet_table`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..names import RawLog
from ..tabular import fields_from_frame, read_parquet_table

__all__ = ["Parquet"]


@dataclass(frozen=True)
class Parquet:
    name = "parquet"
    suffixes = (".parquet", ".pq")
    description = ".parquet"
    items = "columns"
    arrays = False
    trajectory = False

    def sniff(self, path: Path) -> bool:
        return path.suffix.lower() in self.suffixes

    def read(self, path: Path, columns, joint_names) -> RawLog:
        return fields_from_frame(read_parquet_table(path), str(path), columns, joint_names, True)

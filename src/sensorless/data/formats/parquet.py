"""Apache Parquet tables (``.parquet .pq``; :func:`..tabular.read_parquet_table`)."""

from __future__ import annotations

from pathlib import Path

from ..tabular import read_parquet_table
from .base import LogFormat

__all__ = ["PARQUET"]


def _table(path: Path):
    """The Parquet table; its columns are named."""
    return read_parquet_table(path), True


PARQUET = LogFormat("parquet", ".parquet", suffixes=(".parquet", ".pq"), table=_table)

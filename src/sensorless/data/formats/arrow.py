"""Apache Arrow IPC files and Feather (``.arrow .feather``): a table with one column per signal, read
like a Parquet or CSV table (:func:`..tabular.fields_from_frame`: the same column names and patterns).

Both Arrow IPC layouts are accepted: the random-access *file* format (Feather v2, ``pyarrow.feather``,
``pandas.DataFrame.to_feather``) and the *stream* format (``pyarrow.ipc.new_stream``); Feather v1 too.
The table's size is checked against the memory budget (:mod:`..limits`) before it is converted.
"""

from __future__ import annotations

from pathlib import Path

from ...errors import DataError
from ..limits import check_log_size
from .base import LogFormat

__all__ = ["ARROW"]


def read_arrow_table(path: Path):
    """The pandas frame of an Arrow IPC file or stream, or Feather file (DataError naming the file), and
    True: its columns are named."""
    import pyarrow as pa
    import pyarrow.feather as feather

    src = str(path)
    try:
        table = feather.read_table(path, memory_map=True)  # file format (Feather v2) and Feather v1
    except Exception:  # noqa: BLE001  not the file format: try the stream format
        try:
            with pa.memory_map(str(path)) as source:
                table = pa.ipc.open_stream(source).read_all()
        except Exception as exc:  # noqa: BLE001  pyarrow raises ArrowInvalid/OSError/... for a bad file
            raise DataError(f"not a readable Arrow IPC / Feather file ({type(exc).__name__}: {exc})", src) from None
    check_log_size(src, table.num_rows * table.num_columns, f"{table.num_rows} rows × {table.num_columns} columns")
    try:
        df = table.to_pandas()
    except Exception as exc:  # noqa: BLE001  e.g. a column type pandas cannot hold
        raise DataError(f"cannot convert the Arrow table ({type(exc).__name__}: {exc})", src) from None
    df.columns = [str(c) for c in df.columns]
    return df.reset_index(drop=True), True


ARROW = LogFormat("arrow", ".arrow/.feather", suffixes=(".arrow", ".feather"), table=read_arrow_table)

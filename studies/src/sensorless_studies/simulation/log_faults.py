"""Faults a logger leaves at the edges of a text log, written on purpose (tests, benchmarks).

A logger that starts before its clock and buffers are ready writes a few rows of garbage:
values far out of range (1e154 from uninitialised memory) and stamps that run backwards
into the real first sample. A logger killed mid-write leaves its last row cut short.
:func:`write_faulty_csv` writes a table as CSV with both faults.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["write_faulty_csv"]


def write_faulty_csv(table: pd.DataFrame, path: "str | Path", *, leading: int = 9, cut_after: int | None = None,
                     seed: int = 0, time_column: str = "time") -> Path:
    """``table`` as CSV at ``path`` with ``leading`` corrupt rows before its first row (stamps
    running backwards into the first real stamp, a few values up to 1e154, the others
    plausible) and, with ``cut_after``, its last row cut after that many fields (no newline)."""
    rng = np.random.default_rng(seed)
    path = Path(path)
    cols = list(table.columns)
    data = [c for c in cols if c != time_column]
    t0 = float(table[time_column].iloc[0])
    bad = pd.DataFrame(rng.normal(0.0, 1.0, (leading, len(cols))), columns=cols)
    bad[time_column] = t0 + 0.25 * np.arange(leading, 0, -1)  # backwards, ending after the real start
    for k in range(leading):  # absurd magnitudes in a few columns of most rows
        if k % 3 != 2:
            pick = rng.choice(len(data), size=max(1, len(data) // 4), replace=False)
            bad.loc[k, [data[i] for i in pick]] = rng.choice([-1.0, 1.0], pick.size) * 10.0 ** rng.uniform(
                100, 154, pick.size)
    text = pd.concat([bad, table], ignore_index=True).to_csv(index=False, float_format="%.17g")
    if cut_after is not None:
        lines = text.rstrip("\n").split("\n")
        lines[-1] = ",".join(lines[-1].split(",")[:cut_after])
        text = "\n".join(lines)
    path.write_text(text)
    return path

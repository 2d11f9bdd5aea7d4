"""Per-joint noise levels σ for weighted fitting, from the ``weights`` option or a file.

Every method of :func:`~.identify.identify` minimises ``Σ_r w_r ‖W_r π − y_r‖²`` with
``w_r = 1/σ_r²``. ``weights`` is ``"auto"`` (two-step: σ_r from the residual of an
unweighted fit, :func:`~.least_squares.two_step_sigma`), ``"none"``/None (unweighted) or the
σ_r themselves: an array in row order, a mapping ``{joint: σ}`` or, on the command line
(``--weights FILE``), a JSON object ``{"joint": σ, ...}`` or a CSV file of ``joint,σ`` rows
(an optional header line is skipped) or of one header row of joint names over one row of σ.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import OptionError, setting

__all__ = ["WEIGHT_MODES", "check_weights", "read_weights_file", "weights_option"]

WEIGHT_MODES = ("auto", "none")


def check_weights(weights, rows: Sequence[str]) -> str | np.ndarray | None:
    """``weights`` as None (unweighted), ``"auto"`` or an array of per-row σ (positive, finite).

    Accepts None, ``"auto"``, ``"none"``, a sequence in the order of ``rows`` or a mapping
    ``{row: σ}`` covering every row. :class:`~sensorless.errors.OptionError` otherwise,
    naming the joint.
    """
    if weights is None:
        return None
    if isinstance(weights, str):
        if weights not in WEIGHT_MODES:
            raise OptionError(f"weights must be 'auto', 'none' (or None) or per-joint noise levels σ, got {weights!r}")
        return None if weights == "none" else "auto"
    rows = list(rows)
    if isinstance(weights, Mapping):
        return _from_mapping(weights, rows, "weights")
    try:
        sigma = np.asarray(weights, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise OptionError(f"weights must be 'auto', 'none' or per-joint noise levels σ, got {weights!r}") from None
    if sigma.shape != (len(rows),):
        raise OptionError(f"weights: {len(rows)} per-joint noise levels σ needed ({', '.join(rows)}), got {sigma.size}")
    _check_values(dict(zip(rows, sigma)), "weights")
    return sigma


def _check_values(values: Mapping[str, float], where: str) -> None:
    bad = [f"{j} ({v!r})" for j, v in values.items() if not (isinstance(v, float) and math.isfinite(v) and v > 0)]
    if bad:
        raise OptionError(f"{where}: σ must be a positive finite number; bad for joint(s) {', '.join(bad)}")


def _from_mapping(values: Mapping, rows: list[str], where: str) -> np.ndarray:
    unknown = [str(k) for k in values if k not in rows]
    if unknown:
        raise OptionError(f"{where}: unknown joint(s) {', '.join(unknown)}; the joints are {', '.join(rows)}")
    missing = [j for j in rows if j not in values]
    if missing:
        raise OptionError(f"{where}: no σ for joint(s) {', '.join(missing)}")
    parsed = {}
    for j in rows:
        v = values[j]
        try:
            parsed[j] = float(v) if not isinstance(v, bool) else float("nan")
        except (TypeError, ValueError):
            parsed[j] = v  # reported as bad below
    _check_values(parsed, where)
    return np.array([parsed[j] for j in rows])


def read_weights_file(path: str | Path, rows: Sequence[str]) -> np.ndarray:
    """Per-row σ from a JSON object ``{joint: σ}`` or a CSV file (module docstring)."""
    path = Path(path)
    rows = list(rows)
    from ..data.limits import read_small_text

    text = read_small_text(path, "weights file")  # a FIFO or device is refused, not waited on
    if path.suffix.lower() == ".json" or text.lstrip().startswith("{"):
        try:
            values = json.loads(text)
        except json.JSONDecodeError as exc:
            raise OptionError(f"{_src(path)}: not valid JSON ({exc})") from None
        if not isinstance(values, dict):
            raise OptionError(f"{_src(path)}: expected a JSON object {{joint: σ}}, got {type(values).__name__}")
        return _from_mapping(values, rows, f"{_src(path)}")
    table = [[c.strip() for c in line] for line in csv.reader(text.splitlines()) if any(c.strip() for c in line)]
    if len(table) == 2 and len(table[0]) > 2 and all(c in rows for c in table[0]):  # header of joints, row of σ
        if len(table[1]) != len(table[0]):
            raise OptionError(f"{_src(path)}: {len(table[0])} joint names but {len(table[1])} values")
        return _from_mapping(dict(zip(table[0], table[1])), rows, f"{_src(path)}")
    if table and table[0] and table[0][0] not in rows:  # header line such as "joint,sigma"
        table = table[1:]
    if not table or any(len(line) != 2 for line in table):
        raise OptionError(f"{_src(path)}: expected CSV rows 'joint,σ' (one per joint) or a JSON object")
    values: dict[str, str] = {}
    for j, v in table:
        if j in values:
            raise OptionError(f"{_src(path)}: joint {j} listed twice")
        values[j] = v
    return _from_mapping(values, rows, f"{_src(path)}")


def _src(path) -> str:
    return setting("solver.weights", str(path))


def weights_option(value: str, rows: Sequence[str]) -> str | np.ndarray | None:
    """A run's ``solver.weights`` (``auto|none|FILE``, :mod:`sensorless.run.config`) as the ``weights``
    argument of ``identify``."""
    if value in WEIGHT_MODES:
        return check_weights(value, rows)
    if not Path(value).exists():
        raise OptionError(f"{setting('solver.weights')} must be auto, none or a JSON/CSV file of per-joint σ; no file "
                          f"'{value}'")
    return read_weights_file(value, rows)

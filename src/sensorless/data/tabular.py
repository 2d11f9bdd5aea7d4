"""Column-oriented logs: CSV and whitespace text (``.dat``, ``.txt``, ``.log``; with or without a
header row) and Parquet, and the mapping of their columns onto Trajectory fields (names,
``{joint}`` patterns, integer indices or ranges). The words a header may use are the names of
:data:`~sensorless.data.names.FIELD_NAMES`."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from ..errors import DataError, setting, did_you_mean
from .names import FIELD_NAMES, TICK_NAMES, RawLog, normalise, short_list
from .bad_rows import max_edge_rows
from .limits import current_options

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["read_text_table", "read_parquet_table", "fields_from_frame", "numeric_columns", "detect_patterns",
           "TIME_COLUMNS"]

#: time column names (case-insensitive); %time: `rostopic echo -p` (ns), __time: PlotJuggler's CSV export;
#: tick counters are time columns too (read with --time-unit tick)
TIME_COLUMNS = FIELD_NAMES["t"] + TICK_NAMES
#: what starts a comment line of a text table
_COMMENTS = ("#", "%")
#: words a header may use for each field, the first being the default (``q_{joint}``, ...)
FIELD_WORDS = {f: FIELD_NAMES[f] for f in ("q", "v", "a", "tau", "current", "command", "tau_out", "q_motor")}
_SEPARATORS = ("_", ".", "/", ":")
_RANGE = re.compile(r"^\s*(\d*)\s*:\s*(\d*)\s*$")

Columns = Mapping[str, "str | int | Sequence[str | int]"]


def is_number(tok: str) -> bool:
    """Whether the text token parses as a float."""
    try:
        float(tok)
        return True
    except ValueError:
        return False


def read_text_table(path: Path) -> tuple["pd.DataFrame", bool]:
    """The table of a CSV or whitespace-separated text file and whether it has a header (no
    header if the first row is all numbers); ``#`` or ``%`` starts a comment line. A ``%`` line just
    before the data with as many names as the first row has fields is the header (``%time,field.…`` of
    ``rostopic echo -p``, the last ``%`` line of MATLAB-style loggers)."""
    import pandas as pd

    src = str(path)
    first, last_comment, skip = None, None, 0
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            for line in fh:
                if line.strip() and not line.lstrip().startswith(_COMMENTS):
                    first = line
                    break
                skip += 1
                if line.strip():
                    last_comment = line.lstrip()[1:] if line.lstrip().startswith("%") else None
    except OSError as exc:
        raise DataError(f"cannot open: {exc.strerror or exc}", src) from None
    if first is None:
        raise DataError("file is empty", src)
    sep = next((s for s in (",", ";", "\t") if s in first), r"\s+")
    if sep == "\t" and "\t\t" in first.rstrip("\r\n"):
        sep = r"\t+"  # tick<TAB><TAB>value: runs of tabs are one separator (no empty column between them)
    split = lambda ln: [tok.strip().strip("\"'") for tok in (ln.split(sep) if sep not in (r"\s+", r"\t+")  # noqa: E731
                                                           else re.split(sep, ln.strip()))]
    tokens = split(first)
    header = any(tok and not is_number(tok) for tok in tokens)
    names = None
    if last_comment is not None:
        cand = split(last_comment)
        if len(cand) == len(tokens) and all(cand) and not all(is_number(c) for c in cand):
            names, header = cand, True
    try:
        engine = {"engine": "python"} if sep == r"\t+" else {}
        if names is not None:
            df = pd.read_csv(path, sep=sep, header=None, names=names, skiprows=skip, skipinitialspace=True,
                             encoding="utf-8-sig", **engine)
        else:
            df = pd.read_csv(path, sep=sep, header=0 if header else None, skiprows=skip, comment="#",
                             skipinitialspace=True, encoding="utf-8-sig", **engine)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise DataError(f"cannot parse as CSV: {str(exc).strip()}", src) from None
    if header:
        df.columns = [str(c).strip() for c in df.columns]
    # a separator at the end of every line (or doubled) leaves an unnamed column with no value at all
    empty = [c for c in df.columns if (not header or str(c).startswith("Unnamed:")) and df[c].isna().all()]
    if empty and len(empty) < len(df.columns):
        df = df.drop(columns=empty)
        if not header:
            df.columns = range(len(df.columns))
    return df, header


def read_parquet_table(path: Path) -> "pd.DataFrame":
    import pandas as pd

    try:
        import pyarrow.parquet as pq

        meta = pq.ParquetFile(path, page_checksum_verification=True).metadata
    except Exception as exc:  # noqa: BLE001  pyarrow raises ArrowInvalid/OSError/... for a bad file
        raise DataError(f"not a readable Parquet file ({type(exc).__name__}: {exc})", str(path)) from None
    from .limits import check_log_size

    n = meta.num_rows * meta.num_columns
    check_log_size(str(path), n, f"{meta.num_rows} rows × {meta.num_columns} columns")
    try:  # pages written with a CRC (pyarrow's write_page_checksum) are verified: a corrupt page is refused
        df = pd.read_parquet(path, page_checksum_verification=True)
    except Exception as exc:  # pyarrow raises ArrowInvalid/OSError/... for a bad file
        raise DataError(f"not a readable Parquet file ({type(exc).__name__}: {exc})", str(path)) from None
    df.columns = [str(c) for c in df.columns]
    return df.reset_index() if df.index.name is not None else df.reset_index(drop=True)


def _names_from_pattern(pattern: str, avail: list) -> list[str]:
    pre, post = pattern.split("{joint}", 1)
    rx = re.compile(re.escape(pre) + "(.+)" + re.escape(post) + "$")
    return [m.group(1) for c in avail if (m := rx.match(str(c)))]


def _pattern(word: str, sep: str, before: bool) -> str:
    return f"{word}{sep}{{joint}}" if before else f"{{joint}}{sep}{word}"


def detect_patterns(avail: Sequence[str]) -> dict[str, str] | None:
    """The ``{joint}`` patterns of a header without ``columns``: the convention (a word of
    :data:`FIELD_WORDS` before or after the joint name, joined by ``_ . / :``) under which
    the most columns are joint positions; every other field takes the first of its words
    that has a column in that convention (``pos_j1, vel_j1, eff_j1``; ``j1_position,
    j1_velocity, j1_effort``; ``q_j1, v_j1, tau_j1``). None when no column looks like a position."""
    found = _detect(avail)
    return None if found is None else found[0]


def _detect(avail: Sequence[str]) -> tuple[dict[str, str], list[str]] | None:
    """:func:`detect_patterns` and the joint names it found."""
    avail = [str(c) for c in avail]
    have = set(avail)
    best: tuple[int, str, bool, str] | None = None
    for sep in _SEPARATORS:
        for before in (True, False):
            for word in FIELD_WORDS["q"]:
                n = len(_joint_names(_pattern(word, sep, before), avail, sep))
                if n and (best is None or n > best[0]):
                    best = (n, sep, before, word)
    if best is None:
        return None
    _, sep, before, qword = best
    names = _joint_names(_pattern(qword, sep, before), avail, sep)
    # a topic path in front of every name (PlotJuggler: /joint_states/J/position) belongs to the pattern
    common = os.path.commonprefix(names) if all("/" in n for n in names) else ""
    topic = common[: common.rfind("/") + 1]

    def pattern(word: str) -> str:
        return _pattern(word, sep, before).replace("{joint}", topic + "{joint}")

    names = [n[len(topic):] for n in names]
    out = {"q": pattern(qword)}
    for field, words in FIELD_WORDS.items():
        if field != "q":
            found = [w for w in words if any(pattern(w).replace("{joint}", j) in have for j in names)]
            out[field] = pattern((found or words)[0])
    return out, names


def _rostopic_joint_state(df: "pd.DataFrame", src: str) -> tuple[dict[str, list[str]], list[str]] | None:
    """Columns of ``rostopic echo -p`` on a sensor_msgs/JointState topic (``field.name0``,
    ``field.position0``, ``field.velocity0``, ``field.effort0``, ...): the column lists and the
    joint names of the first message; None for other headers."""
    avail = set(map(str, df.columns))
    k = 0
    while f"field.position{k}" in avail:
        k += 1
    if k == 0:
        return None
    names = []
    for i in range(k):
        col = f"field.name{i}"
        if col not in avail:
            names.append(f"joint_{i}")
            continue
        values = df[col].astype(str).unique()
        if len(values) > 1:
            raise DataError(f"column '{col}' changes within the log ({short_list(values, 4)}): the JointState messages "
                            "list their joints in different orders; export one order per file", src)
        names.append(str(values[0]))
    spec = {"q": [f"field.position{i}" for i in range(k)]}
    for field, word in (("v", "velocity"), ("tau", "effort")):
        cols = [f"field.{word}{i}" for i in range(k)]
        if all(c in avail for c in cols):
            spec[field] = cols
    return spec, names


def _joint_names(pattern: str, avail: list, sep: str = "_") -> list[str]:
    """Joint names in the columns matching ``pattern``, without the names that are another
    name plus a qualifier (``cmd_j1`` next to ``j1``: the column ``q_cmd_j1`` is a command)."""
    names = _names_from_pattern(pattern, avail)
    return [n for n in names if not any(m != n and (n.endswith(sep + m) or n.startswith(m + sep)) for m in names)]


def _labels(field: str, spec: Any, avail: list, names: list[str] | None, header: bool, src: str) -> list:
    """Column labels of ``field`` for one ``columns`` entry."""

    def by_index(i: int) -> Any:
        if not 0 <= i < len(avail):
            raise DataError(f"column index {i} (for '{field}') is out of range; the file has {len(avail)} columns", src)
        return avail[i]

    def one(item: Any) -> Any:
        if isinstance(item, (int, np.integer)) and not isinstance(item, bool):
            return by_index(int(item))
        if isinstance(item, str):
            if not header and item.strip().isdigit():
                return by_index(int(item))
            return item
        raise DataError(f"columns['{field}'] entries must be column names or indices, got {item!r}", src)

    if isinstance(spec, str) and "{joint}" in spec:
        if not header:
            raise DataError(f"pattern {spec!r} for '{field}' needs a header row; use an index range like '0:7'", src)
        if not names:
            raise DataError(f"pattern {spec!r} for '{field}' needs joint names: give the robot ({setting('robot')}, "
                            "whose joint names fill the pattern) or name the columns, e.g. "
                            f"{setting('columns', {'q': 'pos_a|pos_b'})}", src)
        labels = [spec.replace("{joint}", j) for j in names]
    elif isinstance(spec, str) and (m := _RANGE.match(spec)):
        start = int(m.group(1) or 0)
        stop = int(m.group(2) or len(avail))
        if not 0 <= start < stop <= len(avail):
            raise DataError(f"column range '{spec}' (for '{field}') does not fit the {len(avail)} columns", src)
        labels = list(avail[start:stop])
    elif isinstance(spec, (str, int, np.integer)):
        labels = [one(spec)]
    elif isinstance(spec, Sequence):
        labels = [one(item) for item in spec]
    else:
        raise DataError(f"columns['{field}'] must be a list, a '{{joint}}' pattern or a range 'a:b', got {spec!r}", src)
    missing = [c for c in labels if c not in avail]
    if missing:
        listed = any("," in str(c) and all(p.strip() in avail for p in str(c).split(",")) for c in missing)
        close = did_you_mean(missing[0], [str(a) for a in avail])
        raise DataError(f"no column(s) {missing} (for '{field}'); {close + ' ' if close else ''}available columns: "
                        f"{short_list(avail)}" + ("; a list of columns is separated by '|' (q=a|b|c)" if listed else ""), src)
    return labels


def numeric_columns(df: "pd.DataFrame", labels: list, field: str, src: str) -> np.ndarray:
    import pandas as pd

    cols = []
    for c in labels:
        s = df[c]
        if field == "t" and pd.api.types.is_datetime64_any_dtype(s):
            if s.isna().any():
                i = int(np.flatnonzero(s.isna().to_numpy())[0])
                raise DataError(f"missing timestamp in column '{c}' at row {i}", src)
            cols.append((s - pd.Timestamp(0, tz=getattr(s.dt, "tz", None))).dt.total_seconds().to_numpy(float))
            continue
        if pd.api.types.is_bool_dtype(s) or pd.api.types.is_datetime64_any_dtype(s) or pd.api.types.is_complex_dtype(s):
            raise DataError(f"column '{c}' (for '{field}') holds {s.dtype} values; expected real numbers", src)
        if pd.api.types.is_numeric_dtype(s):
            cols.append(s.to_numpy(dtype=float, na_value=np.nan))
            continue
        if s.map(lambda x: isinstance(x, (bytes, bytearray, memoryview))).any():
            raise DataError(f"column '{c}' (for '{field}') holds bytes (binary values); expected real numbers", src)
        num = pd.to_numeric(s, errors="coerce")
        text = s.astype(str).str.strip()
        bad = (num.isna() & s.notna() & (text != "")).to_numpy()
        if bad.any():
            rows = np.flatnonzero(bad)
            edge = max_edge_rows(len(bad))
            at_edges = bool(np.all((rows < edge) | (rows >= len(bad) - edge)))
            if not (at_edges and current_options().get("skip_bad_rows")):  # else NaN: bad_rows drops the row
                i = int(rows[0])
                hint = (f"; it is near the start or end of the log: rerun with {setting('skip_bad_rows', True)} to drop "
                        "corrupt rows there" if at_edges else "")
                raise DataError(
                    f"non-numeric value {s.iloc[i]!r} in column '{c}' (for '{field}') at row {i} "
                    f"(0-based data row; {int(bad.sum())} bad cell(s) in this column){hint}",
                    src,
                )
        cols.append(num.to_numpy(dtype=float, na_value=np.nan))
    return np.column_stack(cols) if cols else np.empty((len(df), 0))


def fields_from_frame(
    df: "pd.DataFrame",
    src: str,
    columns: Columns | None,
    joint_names: Sequence[str] | None,
    header: bool,
) -> RawLog:
    """The fields of a table (module docstring); the columns no field uses are listed as unused."""
    avail = list(df.columns)
    if columns is None and not header:
        raise DataError(
            "has no header row; say which columns hold what, e.g. "
            f"{setting('columns', {'q': '0:7', 'v': '7:14', 'tau': '14:21'})} (and {setting('rate', placeholder='HZ')} "
            "if there is no time column)",
            src,
        )
    optional: set[str] = set()
    ros = _rostopic_joint_state(df, src) if columns is None and header else None
    if ros is not None:
        spec, ros_names = ros
        joint_names = ros_names if joint_names is None else joint_names
    elif columns is None:
        spec, found = _detect(avail) or ({f: f"{w[0]}_{{joint}}" for f, w in FIELD_WORDS.items()}, [])
        if joint_names is None and found:
            joint_names = found
        optional = set(FIELD_WORDS) - {"q"}
    else:
        spec = dict(columns)
        if "q" not in spec:
            raise DataError("columns has no 'q' entry (joint positions)", src)
    if header and "t" not in spec:
        lower = {normalise(c): c for c in avail}
        tcol = next((lower[normalise(n)] for n in TIME_COLUMNS if normalise(n) in lower), None)
        if tcol is not None:
            spec["t"] = tcol

    names = list(joint_names) if joint_names is not None else None
    if names is None:
        patterns = [f for f in ("q", *spec) if isinstance(spec.get(f), str) and "{joint}" in spec[f]]
        if patterns and header:
            names = _names_from_pattern(spec[patterns[0]], avail)
            if not names:
                tried = "" if columns is not None else (
                    " (no header convention found either: a word for the field before or after the joint name, "
                    f"e.g. q_J, pos_J, J_position, J.pos; words {dict(FIELD_WORDS)})")
                close = did_you_mean(spec[patterns[0]], avail, cutoff=0.5) if columns is not None else ""
                raise DataError(
                    f"no column matches {spec[patterns[0]]!r} (for '{patterns[0]}'){tried}; "
                    f"{close + ' ' if close else ''}available columns: "
                    f"{short_list(avail)}; say which columns hold what: "
                    f"{setting('columns', {'q': 'pos_{joint}', 'v': 'vel_{joint}', 'tau': 'eff_{joint}'})}",
                    src,
                )

    raw: dict[str, np.ndarray] = {}
    origin: dict[str, str] = {}
    used = {f"field.name{i}" for i in range(len(names or []))} if ros is not None else set()
    for field, entry in spec.items():
        if field in optional:
            present = [entry.replace("{joint}", j) in avail for j in names or []]
            if not any(present):
                continue
            if not all(present):
                absent = [entry.replace("{joint}", j) for j, p in zip(names, present) if not p]
                raise DataError(f"'{field}' columns incomplete: no column(s) {absent}; available columns: {short_list(avail)}", src)
        labels = _labels(field, entry, avail, names, header, src)
        if field == "t" and len(labels) != 1:
            raise DataError(f"'t' must be one column, got {labels}", src)
        values = numeric_columns(df, labels, field, src)
        raw[field] = values[:, 0] if field == "t" else values
        shown = [str(c) if header else f"column {c}" for c in labels]
        origin[field] = shown[0] if len(shown) == 1 else (entry if isinstance(entry, str) else "|".join(shown))
        used.update(labels)
    unused = [str(c) for c in avail if c not in used] if header else [f"column {i}" for i, c in enumerate(avail)
                                                                       if c not in used]
    return RawLog(raw, names, origin, {}, unused)

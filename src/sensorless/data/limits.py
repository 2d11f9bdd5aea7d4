"""Resource limits of the log readers: a memory budget, and line/field bounds for text logs.

A log is read whole and then preprocessed (resampling, zero-phase filters and Savitzky–Golay
derivatives need the whole signal), so it must fit in memory several times over. Before
allocating, every reader checks what the file *declares* (the NPZ zip directory and .npy
headers, HDF5 dataset shapes, Parquet metadata, a CSV's size and first lines) against
:func:`memory_budget`:

* default: :data:`DEFAULT_FRACTION` of the available memory (``psutil``, else ``/proc/meminfo``),
  at most :data:`DEFAULT_CAP` (so that the default does not depend on the machine: a 10⁷-row
  log, hours of 1 kHz data, is refused in seconds everywhere instead of running for many
  minutes where memory happens to allow it);
* ``SENSORLESS_MAX_LOG_MEMORY`` (environment, e.g. ``8GiB``), ``--max-log-memory`` (command
  line) or ``max_memory=`` (library) override it.

The estimate of a whole run is the log's float64 size × :data:`PIPELINE_FACTOR` (measured: peak
RSS of ``load_log`` over the raw array size). A log over budget is an :class:`InputError` naming
the file, the estimate, the limit and the fixes.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
from pathlib import Path
from typing import Iterator

from ..errors import InputError, OptionError, setting

__all__ = ["memory_budget", "parse_size", "format_size", "check_log_size", "prescan_text", "read_options",
           "current_options", "read_small_text", "FIXES", "ENV_VAR", "DEFAULT_FRACTION", "DEFAULT_CAP", "PIPELINE_FACTOR", "MAX_LINE_BYTES", "MAX_FIELDS"]

ENV_VAR = "SENSORLESS_MAX_LOG_MEMORY"
#: share of the available memory one log may expand to by default
DEFAULT_FRACTION = 0.25
#: the default budget never exceeds this [bytes], whatever the machine (module docstring)
DEFAULT_CAP = 4 << 30
#: peak memory of identify (read, preprocess, regressor) over the float64 size the log declares; measured
#: on 10⁶ rows, 7 joints, t/q/v/tau logged: peak RSS growth 2.8× (load_log) and 3.0× (identify --method ols)
PIPELINE_FACTOR = 4.0
#: a CSV/TXT line longer than this is refused (no log needs a MiB per sample)
MAX_LINE_BYTES = 1 << 20
#: a CSV/TXT header or row with more fields than this is refused
MAX_FIELDS = 10_000
#: lines of a text log read by :func:`prescan_text`
PRESCAN_LINES = 200
_UNITS = {"": 1, "b": 1, "k": 1000, "kb": 1000, "m": 1000**2, "mb": 1000**2, "g": 1000**3, "gb": 1000**3,
          "t": 1000**4, "tb": 1000**4, "kib": 1 << 10, "mib": 1 << 20, "gib": 1 << 30, "tib": 1 << 40}

#: what a user can do about a log over budget
FIXES = (f"raise {setting('max_memory', placeholder='SIZE')} (or {ENV_VAR}), or split the log (then "
         f"{setting('decimate', placeholder='N')} to thin each part)")
_OPTIONS: contextvars.ContextVar[dict] = contextvars.ContextVar("sensorless_read_options", default={})


def parse_size(text: "str | int | float", what: str = "`max_memory`") -> int:
    """``'8GiB'``, ``'500MB'``, ``'2g'``, ``1e9`` → bytes (OptionError if not a positive size)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        val, unit = float(text), ""
    else:
        m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:e[+-]?\d+)?)\s*([a-zA-Z]*)\s*", str(text))
        if not m or m.group(2).lower() not in _UNITS:
            raise OptionError(f"{what} must be a size such as 8GiB, 500MB or 2000000000, got {text!r}")
        val, unit = float(m.group(1)), m.group(2).lower()
    size = val * _UNITS[unit]
    if not (size >= 1 and size < 2**63):
        raise OptionError(f"{what} must be a positive size such as 8GiB, got {text!r}")
    return int(size)


def format_size(n: float) -> str:
    for unit, f in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= f:
            return f"{n / f:.1f} {unit}"
    return f"{int(n)} B"


def available_memory() -> int:
    """Available memory [bytes]: ``MemAvailable`` of /proc/meminfo (Linux: the figure psutil reports
    there, without its ~10 ms import), else psutil, else 4 GiB."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except Exception:  # noqa: BLE001  (psutil missing or unsupported platform)
        pass
    return 4 << 30


@contextlib.contextmanager
def read_options(**options) -> Iterator[None]:
    """Reader options for the block: ``max_memory`` (bytes or a size string), ``skip_bad``,
    ``allow_external`` (HDF5), ``accept_implausible_gains``; None values are ignored."""
    token = _OPTIONS.set({**_OPTIONS.get(), **{k: v for k, v in options.items() if v is not None}})
    try:
        yield
    finally:
        _OPTIONS.reset(token)


def current_options() -> dict:
    return _OPTIONS.get()


def memory_budget(max_memory: "str | int | None" = None) -> tuple[int, str]:
    """(bytes a log may expand to, where that limit comes from)."""
    given = max_memory if max_memory is not None else _OPTIONS.get().get("max_memory")
    if given is not None:
        return parse_size(given), setting("max_memory")
    env = os.environ.get(ENV_VAR)
    if env:
        return parse_size(env, ENV_VAR), ENV_VAR
    share = int(available_memory() * DEFAULT_FRACTION)
    if share > DEFAULT_CAP:
        return DEFAULT_CAP, f"the default cap of {format_size(DEFAULT_CAP)}"
    return share, f"{DEFAULT_FRACTION:.0%} of the available memory"


def check_log_size(src: str, n_values: float, what: str, max_memory: "str | int | None" = None) -> None:
    """InputError if ``n_values`` float64 numbers (what the file declares: ``what``) times
    :data:`PIPELINE_FACTOR` exceed the budget."""
    need = float(n_values) * 8 * PIPELINE_FACTOR
    limit, origin = memory_budget(max_memory)
    if need > limit:
        raise InputError(
            f"{src}: log too large for memory: {what} needs about {format_size(need)} to read and preprocess "
            f"(logs are not streamed: resampling and zero-phase filtering need the whole signal), over the limit "
            f"of {format_size(limit)} ({origin}); {FIXES}")


def prescan_text(path: Path, src: str, max_memory: "str | int | None" = None) -> None:
    """Bound a text log before pandas sees it: every line read here under :data:`MAX_LINE_BYTES`
    and :data:`MAX_FIELDS`, and the rows × fields it extrapolates to within the memory budget."""
    size = path.stat().st_size
    lines = fields = nbytes = 0
    with open(path, "rb") as fh:
        while lines < PRESCAN_LINES:
            line = fh.readline(MAX_LINE_BYTES + 1)
            if not line:
                break
            lines += 1
            if len(line) > MAX_LINE_BYTES and not line.endswith(b"\n"):
                raise InputError(f"{src}: line {lines} is longer than {MAX_LINE_BYTES >> 20} MiB; not a log "
                                 "of one sample per line")
            nbytes += len(line)
            n = max(line.count(b","), line.count(b";"), line.count(b"\t"), len(line.split()) - 1) + 1
            if n > MAX_FIELDS:
                raise InputError(f"{src}: line {lines} has {n} fields, more than {MAX_FIELDS}; not a log of "
                                 "joint signals")
            fields = max(fields, n)
    if lines:
        rows = size / (nbytes / lines)
        check_log_size(src, rows * fields, f"about {rows:.3g} rows × {fields} columns", max_memory)


#: largest settings file (gains, weights, --config) read whole
MAX_SMALL_FILE = 16 << 20


def read_small_text(path: "str | os.PathLike", what: str, encoding: str = "utf-8-sig") -> str:
    """The text of a small settings file (``what``: e.g. "--gains file"): a FIFO, device or
    directory and a file over :data:`MAX_SMALL_FILE` are refused (InputError) before it is opened."""
    from ..io import check_input_file

    path = check_input_file(path, what)
    size = path.stat().st_size
    if size > MAX_SMALL_FILE:
        raise InputError(f"{path}: {format_size(size)}, too large for a {what} (limit {format_size(MAX_SMALL_FILE)})")
    try:
        return path.read_text(encoding=encoding)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text {what} (byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read this {what}: {exc.strerror or exc}") from None

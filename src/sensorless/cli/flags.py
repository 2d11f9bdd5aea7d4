"""Messages in the command's language: every setting a library message names (`` `field` `` or
`` `field=value` ``, :func:`sensorless.errors.setting`; a run configuration's `` `group.field` ``,
e.g. `` `solver.gamma` ``, is its field) becomes the running command's option.

The field is looked up among the command's options (``lock_joints`` → ``--lock``, ``rate`` →
``--rate``, ``contain_prior=True`` → ``--contain-prior``); the value is written as that option
takes it (a list as repeated flags or a comma list, a column map as ``'q=0:7;v=7:14'``). A boolean
setting that asks to undo an option the user gave reads "drop --no-contain-prior" (back to the default) or
"--floating-base instead of --fixed-base"; one already in effect says so, so no message tells the user to
drop a flag they never passed. A field the
command has no option for is written in words.
"""

from __future__ import annotations

import ast
import shlex

from ..errors import PYTHON_ONLY_PATTERN, SETTING_PATTERN

__all__ = ["cli_words"]

# library keyword -> the CLI parameter that sets it (when the names differ)
_ALIASES = {
    "lock_joints": "lock",
    "passive_joints": "passive",
    "package_paths": "package_path",
    "allow_external": "allow_hdf5_external",
    "max_memory": "max_log_memory",
    "joint_names": "columns",
    "wrench_frames": "wrench_frame",
    "validation": "validate",
    "cutoff_hz": "lowpass",
    "window": "savgol_window",
    "rate_hz": "rate",
    "accept": "accept_implausible",
}
# library keywords whose CLI option sets the opposite boolean
_NEGATED = {"check_torques": "accept_implausible_torques"}
# values a CLI option spells differently from the Python value
_VALUES = {("ellipsoids", False): "none", ("ellipsoids", None): "none", ("regularization", None): "none",
           ("gains", None): "off"}
# what to write for a value left to the user
_PLACEHOLDERS = {"rate": "HZ", "prior": "FILE", "lock": "JOINT", "passive": "JOINT", "columns": "'q=...;v=...;tau=...'",
                 "package_path": "DIR", "lowpass": "HZ", "time_unit": "UNIT", "gains": "FILE", "trim": "START:END",
                 "angle_unit": "deg", "frame": "FRAME", "max_log_memory": "SIZE"}


def _context():
    try:
        from typer.main import get_current_context
    except ImportError:  # pragma: no cover - older typer on plain click
        from click import get_current_context
    return get_current_context(silent=True)


def _source_name(ctx, name: str) -> str | None:
    try:
        src = ctx.get_parameter_source(name)
    except Exception:  # noqa: BLE001
        return None
    return None if src is None else getattr(src, "name", str(src))


def _source_given(ctx, name: str) -> bool:
    """Whether the user set option ``name`` (command line, environment or the --config file)."""
    return _source_name(ctx, name) in ("COMMANDLINE", "ENVIRONMENT", "DEFAULT_MAP")


def _parse(text: str | None):
    if text is None:
        return None, True
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return text, True  # a placeholder such as HZ or FILE
    return (text, True) if value is Ellipsis else (value, False)


def _quote(v) -> str:
    s = str(v)
    return s if s and all(c.isalnum() or c in "-_./:,+@%" for c in s) else shlex.quote(s)


def _value_words(v) -> str:
    if isinstance(v, dict):
        return ";".join(f"{k}={_value_words(x)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return ",".join(_value_words(x) for x in v)
    return "..." if v is Ellipsis else str(v)


def _in_words(field: str, value, placeholder: bool) -> str:
    words = field.rsplit(".", 1)[-1].replace("_", " ")
    if value is None or placeholder:
        return words
    return f"{words} {_value_words(value)}"


def _param(field: str, params: dict):
    """The command's option for ``field``: same name, an alias, or the one option named ``*_field``
    (``mode`` → ``--contact-mode`` on a command whose only mode is the contact mode)."""
    name = _ALIASES.get(field, field)
    if name in params or field in params:
        return params.get(name) or params[field]
    ends = [p for n, p in params.items() if n.endswith("_" + field)]
    return ends[0] if len(ends) == 1 else None


def _flag(field: str, text: str | None, ctx) -> str:
    """The option of the running command that sets ``field`` to the value ``text`` (see module docstring);
    a run configuration's ``group.field`` is its field (``solver.gamma`` → ``--gamma``)."""
    field = field.rsplit(".", 1)[-1]
    params = {p.name: p for p in ctx.command.params if getattr(p, "param_type_name", "") == "option"}
    value, placeholder = _parse(text)
    if field in _NEGATED and field not in params and isinstance(value, bool):
        field, value = _NEGATED[field], not value
    p = _param(field, params)
    if p is None:
        return _in_words(field, value, placeholder)
    name = p.name
    opt = next((o for o in p.opts if o.startswith("--")), p.opts[0])
    if getattr(p, "is_flag", False) and isinstance(value, bool) and not placeholder:
        off = next((o for o in getattr(p, "secondary_opts", ()) if o.startswith("--")), None)
        want = opt if value else off
        if want is None:  # a one-way flag (--force): False means leaving it out
            return f"drop {opt}" if _source_given(ctx, name) and ctx.params.get(name) else f"{opt} not given, already in effect"
        if ctx.params.get(name) == value:
            return f"{want}, already in effect"
        if _source_given(ctx, name):  # the user gave the opposite flag
            typed = off if value else opt
            where = " (in the --config file)" if _source_name(ctx, name) == "DEFAULT_MAP" else ""
            return f"drop {typed}{where}" if p.default == value else f"{want} instead of {typed}{where}"
        return want
    if text is None:  # the option named, not a value suggested
        return opt
    special = next((w for (f, v), w in _VALUES.items() if f in (field, name) and v is value), None)
    if special is not None:
        return f"{opt} {special}"
    if field == "joint_names" and name == "columns":  # the log's column of each joint, in the robot's order
        names = "COL|COL|..." if value is None or placeholder else "|".join(map(str, value))
        return f"{opt} {shlex.quote('q=' + names)}"
    if value is None or placeholder:
        ph = value if placeholder and value not in (None, "...") else _PLACEHOLDERS.get(name, name.upper())
        return f"{opt} {ph}"
    if isinstance(value, (list, tuple)) and getattr(p, "multiple", False):
        return " ".join(f"{opt} {_quote(_value_words(v))}" for v in value)
    return f"{opt} {_quote(_value_words(value))}"


def cli_words(message: object, ctx=None) -> str:
    """``message`` with every `` `field[=value]` `` setting written as the running command's
    option (module docstring); unchanged outside a command."""
    text = str(message)
    ctx = ctx or _context()
    if ctx is None:
        return text
    text = PYTHON_ONLY_PATTERN.sub("", text)
    if "`" not in text:
        return text
    return SETTING_PATTERN.sub(lambda m: _flag_or_words(m.group(1), m.group(2), ctx), text)


def _flag_or_words(field: str, text: str | None, ctx) -> str:
    try:
        return _flag(field, text, ctx)
    except Exception:  # noqa: BLE001 - the message matters more than its wording
        return _in_words(field, *_parse(text))

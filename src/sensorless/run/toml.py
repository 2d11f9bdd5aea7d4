"""A TOML file onto :class:`~.config.RunConfig`: each key is a field (``-`` or ``_``), top-level
(``method = "lmi"``) or under its group's table (``[solver]`` ``gamma = 1e-3``); an unknown key is an
error naming the key and the file. Consent and overrides (``trust_xacro``, ``allow_hdf5_external``,
``force``, ``accept_*``: the fields marked ``cli_only``) are never taken from a file."""

from __future__ import annotations

import tomllib
from pathlib import Path

from ..errors import OptionError, setting
from .config import GROUPS, RunConfig, config_fields

__all__ = ["read_run_toml", "run_config_from_toml", "consent_refused"]


def consent_refused(path, keys) -> OptionError:
    """The error for consent and override fields (``trust_xacro``, ``allow_hdf5_external``, ``force``,
    ``accept_*``) found in the file ``path``: a file someone else wrote must not give them."""
    from .config import config_fields

    fields = config_fields()
    names = ", ".join(setting(f"{fields[k][0]}.{k}" if k in fields else k) for k in keys)
    return OptionError(f"{path}: {names} (consent to run a file's code, to read external data, to replace an "
                       "output or to accept implausible data) is taken from the command line only, or a RunConfig "
                       "made in Python; never from a file")


def read_run_toml(path: str | Path, *, keep_consent: bool = False) -> dict:
    """``{field name: value}`` of the TOML file ``path`` (module docstring; OptionError naming the file
    and the key). A string where a field takes several values is one value (``trim = "2:-3"``). A consent
    field is refused (:func:`consent_refused`) unless ``keep_consent`` (the caller refuses it)."""
    from ..data.limits import read_small_text

    src = str(path)
    try:
        doc = tomllib.loads(read_small_text(Path(path), "config file", encoding="utf-8"))  # FIFOs refused
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise OptionError(f"{src}: not a readable TOML file ({exc})") from None
    except (RecursionError, MemoryError):
        raise OptionError(f"{src}: not a usable TOML file (nested too deeply)") from None
    fields = config_fields()
    flat: dict = {}
    unknown = []
    for key, value in doc.items():
        name = str(key).replace("-", "_")
        if name in GROUPS and isinstance(value, dict):  # [solver] gamma = ...
            for k, v in value.items():
                sub = str(k).replace("-", "_")
                if fields.get(sub, (None,))[0] == name:
                    flat[sub] = v
                else:
                    unknown.append(f"{name}.{k}")
        elif name in fields:
            flat[name] = value
        else:
            unknown.append(str(key))
    if unknown:
        raise OptionError(f"{src}: unknown key(s) {', '.join(sorted(unknown))}; keys are the run's options "
                          f"(those of `sensorless identify`), e.g. method, data, out, savgol_window")
    refused = [k for k in flat if fields[k][1].metadata["cli_only"]]
    if refused and not keep_consent:
        raise consent_refused(path, refused)
    for k, v in flat.items():
        if isinstance(v, str) and isinstance(fields[k][1].default, tuple):
            flat[k] = [v]
    return flat


def run_config_from_toml(path: str | Path, **overrides) -> RunConfig:
    """The :class:`RunConfig` of the TOML file ``path``, with ``overrides`` (field names) winning."""
    return RunConfig.from_options(str(path), **{**read_run_toml(path), **overrides})

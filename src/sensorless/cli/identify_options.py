"""The options of `sensorless identify`, one per field of :class:`sensorless.run.RunConfig`: the flag is
the field's name (``solver.gamma`` → ``--gamma``) or its ``flags``, the default is the field's default,
the help is the field's, or that of the option of the same name other commands share (``--gains``,
``--trim``, ``--lock``, ...). A field with ``choices`` lists them in ``--help`` and refuses anything else."""

from __future__ import annotations

import dataclasses
from enum import StrEnum
from pathlib import Path
from typing import Any, List, Optional

import typer

from ..run.config import RunConfig, config_fields
from .channel_options import base_velocity_option, pose_max_gap_option, wrench_frame_option
from .common import (READING_OPTIONS, ROBOT_SOURCE_OPTIONS, add_options, force_option, floating_base_option,
                     gains_option, lock_option, max_gap_option, resample_option, robot_option, time_unit_option,
                     velocity_option)
from .frames import ADD_FRAME_OPTION
from .logs import trim_option

__all__ = ["identify_options", "run_config", "option_table"]

#: fields whose option (and help) the commands share
SHARED = {"robot": robot_option, "gains": gains_option, "trim": trim_option, "resample": resample_option,
          "velocity": velocity_option, "max_gap": max_gap_option, "time_unit": time_unit_option,
          "base_velocity": base_velocity_option, "pose_max_gap": pose_max_gap_option,
          "wrench_frame": wrench_frame_option, "lock": lock_option, "floating_base": floating_base_option,
          "force": force_option, **{k: make for k, (_, make) in {**READING_OPTIONS, **ROBOT_SOURCE_OPTIONS,
                                                                  **ADD_FRAME_OPTION}.items()}}
_TYPES = {"str": str, "int": int, "float": float, "bool": bool, "str | float": str, "Path | None": Optional[Path],
          "str | None": Optional[str], "int | None": Optional[int], "float | None": Optional[float],
          "bool | None": Optional[bool], "tuple[str, ...]": Optional[List[str]], "tuple[Path, ...]": Optional[List[Path]]}


def _annotation(f: dataclasses.Field):
    choices = f.metadata["choices"]
    if choices:
        enum = StrEnum("".join(w.title() for w in f.name.split("_")), {v.replace("-", "_"): v for v in choices})
        return enum if f.default is not None else Optional[enum]
    if f.name in ("data", "validate"):
        return List[Path]
    return _TYPES[str(f.type)]


def _option(f: dataclasses.Field, group: str):
    """The typer option of config field ``f`` (module docstring), listed under its group in ``--help``."""
    default: Any = ... if f.metadata["required"] else f.default
    if isinstance(default, tuple):
        default = list(default) if f.name == "validate" else None
    if f.name in SHARED:
        info = SHARED[f.name]()
        info.default = default
    else:
        info = typer.Option(default, *f.metadata["flags"], help=f.metadata["help"])
    info.rich_help_panel = group
    return info


def option_table() -> dict:
    """``{field name: (annotation, option factory)}`` for :func:`~.common.add_options`."""
    return {name: (_annotation(f), lambda f=f, g=g: _option(f, g)) for name, (g, f) in config_fields().items()}


def identify_options(fn):
    """Decorator: every config field as an option; the command gets them in one ``options`` dict."""
    return add_options(option_table(), into="options")(fn)


def run_config(options: dict, source: Optional[Path] = None) -> RunConfig:
    """The :class:`RunConfig` of the command's ``options`` (choices as plain strings, None lists as empty)."""
    def plain(v):
        if isinstance(v, StrEnum):
            return str(v)
        if isinstance(v, list):
            return tuple(plain(x) for x in v)
        return v

    fields = config_fields()
    values = {k: (() if v is None and isinstance(fields[k][1].default, tuple) else plain(v)) for k, v in options.items()}
    return RunConfig.from_options(None if source is None else str(source), **values)

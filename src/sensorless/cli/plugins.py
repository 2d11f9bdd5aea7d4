"""Commands other installed packages add to ``sensorless`` (the studies: ``example``, ``experiment``,
``benchmark``, ``demo``).

A distribution registers a typer app under the entry-point group :data:`GROUP`; the entry point's name
is the command's (``benchmark = "package.cli:benchmark_app"``, see studies/pyproject.toml). The root group resolves its
own commands first, so a library command never scans the installed packages; the entry points are read
(``importlib.metadata``) and loaded only when ``--help`` lists the commands or a command is not the
library's own. Without the studies package, its commands stay listed and say how to install it.
"""

from __future__ import annotations

import functools
from typing import List, Optional

import typer
from typer.core import TyperGroup

__all__ = ["GROUP", "STUDY_COMMANDS", "STUDIES_HINT", "PluginGroup", "command_entry_points"]

#: entry-point group of the commands other packages add
GROUP = "sensorless.commands"
#: the commands of the studies package (``studies/`` beside the library in the repository)
STUDY_COMMANDS = ("example", "experiment", "benchmark", "demo")
STUDIES_HINT = ("in the studies package sensorless-studies, not installed: `pip install -e studies` from the "
                "repository's clone (`make` installs both packages into .venv)")


@functools.lru_cache(maxsize=1)
def command_entry_points() -> dict:
    """``{command name: EntryPoint}`` of the group :data:`GROUP` (read once per process)."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=GROUP)}


def _load(ep, name: str):
    """The command of an entry point's typer app, named ``name``."""
    obj = ep.load()
    if not isinstance(obj, typer.Typer):
        raise TypeError(f"entry point {name} = {ep.value} (group {GROUP}) is not a typer.Typer app")
    cmd = typer.main.get_command(obj)
    cmd.name = name
    return cmd


def _not_installed(name: str):
    """A stand-in for a study command: listed in --help, and one red line (exit 2) when run."""
    stub = typer.Typer(add_completion=False)

    @stub.command(name, help="(not installed) a command of sensorless-studies: `pip install -e studies`", add_help_option=False,
                  context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
    def run(args: Optional[List[str]] = typer.Argument(None, hidden=True)) -> None:
        from rich.text import Text

        from .console import err_console

        err_console.print(Text.assemble(("error:", "bold red"), f" `sensorless {name}` is {STUDIES_HINT}"),
                          highlight=False, soft_wrap=True)
        raise typer.Exit(2)

    cmd = typer.main.get_command(stub)
    cmd.name = name
    return cmd


class PluginGroup(TyperGroup):
    """The root group: its own commands, then those of :data:`GROUP` entry points, loaded on first use."""

    def list_commands(self, ctx) -> list[str]:
        own = super().list_commands(ctx)
        more = [n for n in command_entry_points() if n not in own]
        return own + more + [n for n in STUDY_COMMANDS if n not in own and n not in more]

    def get_command(self, ctx, cmd_name: str):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is not None:
            return cmd
        ep = command_entry_points().get(cmd_name)
        if ep is not None:
            cmd = _load(ep, cmd_name)
        elif cmd_name in STUDY_COMMANDS:
            cmd = _not_installed(cmd_name)
        else:
            return None
        self.add_command(cmd, cmd_name)
        return cmd

"""`sensorless example NAME --out DIR`: the data a documented command uses (simulated, seeded).

`sensorless example --list` names them; each doc's first block makes its data this way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from sensorless.errors import OptionError, did_you_mean
from sensorless.cli.common import atomic_outdir, force_option, guarded
from sensorless.cli.console import console

__all__ = ["example", "example_app"]

#: `sensorless example` (one command)
example_app = typer.Typer(add_completion=False)


@example_app.command()
@guarded
def example(
    name: Optional[str] = typer.Argument(None, help="which example (`--list` names them)"),
    out: Optional[Path] = typer.Option(None, help="new folder for the files"),
    full: bool = typer.Option(False, "--full", help="the size the docs' figures were measured on (slower)"),
    seed: int = typer.Option(0, help="random seed of the simulation"),
    list_: bool = typer.Option(False, "--list", help="list the examples and exit"),
    force: bool = force_option(),
) -> None:
    """Write the logs, models and files a quickstart or doc uses."""
    from ..example_data import EXAMPLES, example_names, example_summary, write_example

    if list_ or name is None:
        for n in example_names():
            console.print(f"{n:<20} {example_summary(n)}", soft_wrap=True)
        if name is None and not list_:
            raise OptionError("name an example (`sensorless example --list`), e.g. `sensorless example "
                              f"{example_names()[0]} --out DIR`")
        return
    if name not in EXAMPLES:
        hint = did_you_mean(name, example_names())
        raise OptionError(f"unknown example '{name}'{'; ' + hint if hint else ''} (`sensorless example --list`)")
    if out is None:
        raise OptionError(f"--out DIR is required (e.g. `sensorless example {name} --out {name}`)")
    with atomic_outdir(out, force) as tmp:
        files = write_example(name, tmp, full=full, seed=seed)
    console.print(f"{name}: wrote {', '.join(files)} in {out}/", soft_wrap=True)

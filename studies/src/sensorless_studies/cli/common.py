"""The studies' command groups and their shared options (the library's CLI pieces come from
:mod:`sensorless.cli.common`)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Optional

import typer

from sensorless.cli.common import add_options, force_option, guarded, output_file
from sensorless.cli.console import console

__all__ = ["bench_app", "experiment_app", "bench_out_option", "bench_command", "experiment_options", "write_result"]

bench_app = typer.Typer(add_completion=False, no_args_is_help=True, help="Speed and scale benchmarks (JSON output).")
experiment_app = typer.Typer(add_completion=False, no_args_is_help=True, help="Reproductions of the papers' studies (JSON + figures).")


def bench_out_option(name: str):
    """``--out`` of a benchmark: ``sensorless-bench/NAME.json`` in the working directory (never a tracked
    file; the repository's record in studies/benchmarks/results/ is rewritten only by naming it)."""
    return typer.Option(Path(f"sensorless-bench/{name}.json"), help="JSON file to write")


def bench_command(name: str, results: Optional[str] = None):
    """Decorator: the (guarded) command ``sensorless benchmark NAME``, given an ``--out`` option
    (:func:`bench_out_option` of ``results``, default ``name``) to which the result dict the
    command returns is written (:func:`write_result`); one definition for every benchmark."""

    def deco(fn):
        @functools.wraps(fn)
        def run(*args, out: Path, **kwargs) -> None:
            write_result(fn(*args, **kwargs), out)

        with_out = add_options({"out": (Path, lambda: bench_out_option(results or name))})(run)
        return bench_app.command(name)(guarded(with_out))

    return deco


def experiment_options(out: str, quick: str, seed: str):
    """Decorator: a study's ``--out`` (default ``out``), ``--quick`` / ``--seed`` (help ``quick``,
    ``seed``) and ``--force`` options; one definition for the ``experiment`` commands."""
    return add_options({
        "out": (Path, lambda: typer.Option(Path(out), help="output directory (written atomically; default in sensorless-results/)")),
        "quick": (bool, lambda: typer.Option(False, "--quick", help=quick)),
        "seed": (int, lambda: typer.Option(0, help=seed)),
        "force": (bool, force_option),
    })


def write_result(res: dict, out: Path) -> None:
    """A benchmark's JSON (parent folders made, written atomically) and the line saying so."""
    from sensorless.io import write_json_atomic

    output_file(out, force=True)  # benchmark results are regenerated in place; never a directory or FIFO
    write_json_atomic(res, out)
    console.print(f"wrote {out}")

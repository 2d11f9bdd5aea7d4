"""`sensorless identify`: options → :class:`sensorless.run.RunConfig` → :func:`sensorless.run.identify_run`
→ the model folder (result.json, model.urdf, joint_terms.json, torques.png, report.html)."""

from __future__ import annotations

from contextlib import nullcontext
from pathlib import Path
from typing import Optional

from .common import MultiValueCommand, app, atomic_outdir, guarded, printed_warnings
from .console import console
from .flags import cli_words
from .identify_options import identify_options, run_config
from .options import check_config, config_option
from .progress import progress_bars


@app.command(cls=MultiValueCommand)
@guarded
@identify_options
def identify(config: Optional[Path] = config_option(), *, options: dict) -> None:
    """Identify a dynamic model from logs; write result.json, model.urdf, joint_terms.json, torques.png, report.html.

    --data accepts glob patterns, '**' recursive (quote them: --data 'logs/**/*.parquet')."""
    _cheap_exit()
    plotter = _start_plotter() if options["plot"] else None  # first: it imports matplotlib in parallel
    try:
        _identify(config, options, plotter)
    finally:
        if plotter is not None:
            plotter.close()


def _identify(config: Optional[Path], options: dict, plotter) -> None:
    from ..report import metrics_table
    from ..run.pipeline import identify_run, jobs_in, run_inputs
    from .identify_outputs import print_bodies, print_floating_base, summary_line

    check_config()
    cfg = run_config(options, config)
    out = cfg.execution.out
    # the figure process is stopped first on an error: nothing it writes outlives the hidden folder's removal
    with atomic_outdir(out, cfg.execution.force, inputs=run_inputs(cfg)) as tmp, progress_bars() as bars, \
            (plotter if plotter is not None else nullcontext()):
        sent = []  # the figures go to the plot process as soon as the run has them
        run = identify_run(cfg, bars=bars, say=lambda line: console.print(cli_words(line), highlight=False, soft_wrap=True),
                           figures=lambda jobs: sent.append(plotter is not None and plotter.submit(jobs_in(tmp, jobs))),
                           figure_layouts=None if plotter is None else lambda specs: plotter.prepare(jobs_in(tmp, specs)))
        for title, cols in run.tables:
            console.print(metrics_table(title, cols))
        print_bodies(run.result)
        print_floating_base(run.doc)
        run.doc["terminal_warnings"] = printed_warnings()  # report.html shows what the terminal said
        run.write(tmp, plotter=plotter, submitted=any(sent))
    console.print(summary_line(run.result, cfg.solver.method, run.skipped, out))


def _cheap_exit() -> None:
    """At interpreter exit, move every object to the garbage collector's permanent generation
    (``gc.freeze``) first: the collections of the shutdown then skip the objects the run made
    (cvxpy's problems among them; measured 1.3–2.1 s from the exit handlers to the end of the
    process on a loaded machine, 0.14–0.30 s with it). Everything the command writes is closed
    before then; the OS frees the memory."""
    import atexit
    import gc

    if not getattr(_cheap_exit, "registered", False):
        atexit.register(gc.freeze)
        _cheap_exit.registered = True


def _start_plotter():
    """The process drawing identify's figures (:class:`~.figure_process.FigureProcess`), when a core is
    idle for it; else None (the command draws them)."""
    from . import figure_process

    return figure_process.FigureProcess() if figure_process.idle_core() else None

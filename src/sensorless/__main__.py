"""The ``sensorless`` executable and ``python -m sensorless``: the command-line interface
(:mod:`sensorless.cli`) in a process whose cyclic garbage collector runs less often.

A command is a short process that allocates most of its objects once, importing its libraries:
with CPython's default thresholds (700, 10, 10) ``identify`` ran ~145 collections that scanned those
objects again and again, ~0.04 s of its ~0.6 s on the UR5 hard case. :data:`GC_THRESHOLDS` collect
the youngest generation every 50 000 allocations instead (cycles are still collected); set before
the CLI is imported, so that its imports count too. A library user's process keeps its own settings,
and so does ``sensorless stream`` (:data:`REAL_TIME_COMMANDS`): in a loop that runs for hours at 1 kHz
a collection's pause matters more than the collector's total work, and one that scans 50 000 objects
at once is a longer pause.
"""

from __future__ import annotations

__all__ = ["GC_THRESHOLDS", "REAL_TIME_COMMANDS", "main"]

GC_THRESHOLDS = (50_000, 20, 20)
#: the commands that keep the interpreter's thresholds
REAL_TIME_COMMANDS = ("stream",)


def main() -> None:
    """Run the command line in ``sys.argv``."""
    import gc
    import sys

    command = sys.argv[1] if len(sys.argv) > 1 else None
    if command not in REAL_TIME_COMMANDS:
        gc.set_threshold(*GC_THRESHOLDS)
    from .cli import app

    app()


if __name__ == "__main__":
    main()

"""The ``sensorless`` executable and ``python -m sensorless``: the command-line interface
(:mod:`sensorless.cli`) in a process whose cyclic garbage collector runs less often.

A command is a short process that allocates most of its objects once, importing its libraries:
with CPython's default thresholds (700, 10, 10) ``identify`` ran ~145 collections that scanned those
objects again and again, ~0.04 s of its ~0.6 s on the UR5 hard case. :data:`GC_THRESHOLDS` collect
the youngest generation every 50 000 allocations instead (cycles are still collected); set before
the CLI is imported, so that its imports count too. A library user's process keeps its own settings.
"""

from __future__ import annotations

__all__ = ["GC_THRESHOLDS", "main"]

GC_THRESHOLDS = (50_000, 20, 20)


def main() -> None:
    """Run the command line in ``sys.argv``."""
    import gc

    gc.set_threshold(*GC_THRESHOLDS)
    from .cli import app

    app()


if __name__ == "__main__":
    main()

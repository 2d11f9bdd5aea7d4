"""The fuzz classes of issue 26, run by ``studies/benchmarks/fuzz.py`` (``--classes``).

Each module has ``setup(d, scale) -> ctx`` (once per worker process, in its private folder ``d``),
``case(rng, d, ctx) -> (outcome, message)`` and optionally ``teardown(ctx)``; outcomes are those of
:data:`.common.OUTCOMES`, or ``"skipped"`` (counted under ``notes``, not as an input).
"""

from __future__ import annotations

import importlib

#: class → (default number of inputs at --scale 1, inputs per worker process)
NEW = {"outputs": (1500, 250), "descriptions": (1000, 250), "oversize": (400, 100), "model_folder": (400, 100),
       "containers": (600, 150), "numerics": (600, 150), "formats": (800, 200), "service": (400, 100)}


def module(kind: str):
    return importlib.import_module(f"{__name__}.{kind}")

"""Lazy package exports (PEP 562): a public name is imported from its submodule on first use.

``import sensorless.cli`` (and ``sensorless --help``) then loads no SciPy signal processing,
Pinocchio, cvxpy, matplotlib or torch; each is imported by the code that needs it.
"""

from __future__ import annotations

import importlib
from typing import Callable


def lazy_exports(namespace: dict, exports: dict[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for the package whose ``globals()`` is ``namespace``; ``exports`` maps
    each lazy name to its submodule, relative to the package (``{"Trajectory": ".data"}``).

    The imported value is cached in the package namespace, so the lookup runs once per name. A lazy
    name must differ from every submodule name (importing a submodule binds its name on the package).
    """
    ns, package = namespace, namespace["__name__"]

    def __getattr__(name: str) -> object:
        mod = exports.get(name)
        if mod is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(mod, package), name)
        ns[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(ns) | set(exports))

    return __getattr__, __dir__

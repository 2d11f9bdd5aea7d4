"""Start-up work a command would do for nothing: NumPy modules that SciPy's import loads unused.

SciPy builds its array-API view of NumPy (``scipy._lib.array_api_compat.numpy``) by copying every
public NumPy name, which imports the submodules NumPy otherwise loads only when first used:
``numpy.f2py`` (the Fortran wrapper generator) and ``numpy.testing`` (with ``unittest`` and
``importlib.metadata``), ~0.05 s of every command that fits, for modules no command uses.
:func:`defer_numpy_extras` registers both as lazy modules (:class:`importlib.util.LazyLoader`): the
copy holds module objects that execute on their first attribute access, the same objects NumPy's
``numpy.testing`` then returns. :func:`before_scipy` has it done just before SciPy's first import.
"""

from __future__ import annotations

import importlib.abc
import sys

__all__ = ["DEFERRED", "before_scipy", "defer_numpy_extras"]

DEFERRED = ("numpy.f2py", "numpy.testing")


def defer_numpy_extras() -> list[str]:
    """Register each of :data:`DEFERRED` not yet imported as a lazy module of NumPy (imported here);
    returns the names registered."""
    import importlib.util

    import numpy

    done = []
    for name in DEFERRED:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            continue
        spec.loader = importlib.util.LazyLoader(spec.loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)  # lazy: the module's code runs on its first attribute access
        setattr(numpy, name.rpartition(".")[2], module)
        done.append(name)
    return done


class _BeforeScipy(importlib.abc.MetaPathFinder):
    """Consulted first for every import; at SciPy's, defers NumPy's extras, then leaves the path."""

    def find_spec(self, name, path=None, target=None):
        if name == "scipy":
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            try:
                defer_numpy_extras()
            except Exception:  # noqa: BLE001 - an optimisation only: SciPy then imports them as it always did
                pass
        return None  # the regular finders import the module


def before_scipy() -> None:
    """Defer NumPy's extras (:func:`defer_numpy_extras`) when SciPy is first imported; nothing if it
    already is."""
    if "scipy" not in sys.modules and not any(isinstance(f, _BeforeScipy) for f in sys.meta_path):
        sys.meta_path.insert(0, _BeforeScipy())

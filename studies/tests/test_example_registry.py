"""Every example module under sensorless_studies.example_data is registered, and every registered one has a writer."""

from __future__ import annotations

import pkgutil

import sensorless_studies.example_data as ex


def test_every_example_module_is_registered_and_writes():
    modules = {m.name for m in pkgutil.iter_modules(ex.__path__)}
    assert modules == set(ex.EXAMPLES.values())
    for name in ex.example_names():
        assert ex.example_summary(name)
        assert callable(ex._module(name).write)

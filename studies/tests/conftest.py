"""The library's shared fixtures (tests/conftest.py: robots, the seeded Pinocchio generator, a Panda log)
for the studies' tests."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "sensorless_library_conftest", Path(__file__).resolve().parents[2] / "tests" / "conftest.py")
_library = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_library)

panda, ur5, solo12, kuka, rng, panda_train_npz = (
    _library.panda, _library.ur5, _library.solo12, _library.kuka, _library.rng, _library.panda_train_npz)
_seed_pinocchio = _library._seed_pinocchio
REALDATA, realdata = _library.REALDATA, _library.realdata

"""docs/gen_api.py runs and documents every name of every package's __all__."""

from __future__ import annotations

import importlib
import runpy
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_api_page_covers_every_public_name(tmp_path):
    gen = runpy.run_path(str(DOCS / "gen_api.py"))
    text, covered = gen["render"]()
    assert "sensorless.data" in covered and "sensorless" in covered
    for pkg in gen["packages"]():
        names = getattr(importlib.import_module(pkg), "__all__", [])
        for name in names:
            assert f"### `{pkg}.{name}`" in text, f"{pkg}.{name} missing from the API page"
    assert "### `sensorless.data.read_trajectory` (function)" in text
    assert "read_trajectory(path: 'str | Path', *, joint_names" in text  # signatures come from inspect

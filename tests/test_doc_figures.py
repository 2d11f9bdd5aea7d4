"""Measured figures quoted in the docs equal their benchmark JSON (docs/gen_figures.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _gen():
    spec = importlib.util.spec_from_file_location("gen_figures", ROOT / "docs" / "gen_figures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_marked_figure_matches_its_json():
    gen = _gen()
    cache, n, stale = {}, 0, []
    for path in gen.doc_files():
        text = path.read_text(encoding="utf-8")
        n += len(gen.MARK.findall(text))
        stale += [f"{path.name}: {old} != {new} ({spec})" for spec, old, new in gen.rewrite(text, cache)[1]]
    assert n >= 50
    assert not stale, "run `python docs/gen_figures.py`:\n" + "\n".join(stale)


def test_a_drifted_figure_is_caught_and_rewritten():
    gen = _gen()
    text = "max 9.999<!--fig real_arm.json acceptance.nrmse_ratio_max .3f--> and 1,234<!--fig fuzz.json totals.ok ,d-->"
    new, changed = gen.rewrite(text, {})
    assert [c[1] for c in changed] == ["9.999"]
    again, none = gen.rewrite(new, {})
    assert none == [] and again == new


def test_aggregate_and_scale():
    gen = _gen()
    held = gen.figure("held_monitor.json seeds.*.order1.found sum d", {})
    assert held == "50"
    assert gen.figure("real_arm.json acceptance.gains_interval_coverage .0f x100", {}) == "93"

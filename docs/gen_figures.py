"""Write the measured figures quoted in README.md and docs/*.md from the benchmark JSON they come from.

    python docs/gen_figures.py           # rewrite every marked figure from its JSON
    python docs/gen_figures.py --check   # list the figures that differ from their JSON; exit 1 if any

A figure is marked by an HTML comment right after it (invisible on GitHub)::

    held-out NRMSE 2.31<!--fig peers.json cases.hard.lmi.mean_nrmse_percent .2f-->

``FILE PATH [FORMAT] [xSCALE] [AGG]``: FILE is under studies/benchmarks/results/ (or repository-relative
when it holds a ``/``); PATH is dotted keys and list indices, ``*`` for every element; AGG
(``max``, ``min``, ``mean``, ``sum``) folds a ``*`` path; SCALE multiplies (``x100`` for percent);
FORMAT is a Python format spec (default ``g``).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "studies" / "benchmarks" / "results"
NUMBER = r"[-+−]?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?:[eE][-+]?\d+)?"
MARK = re.compile(rf"(?P<value>{NUMBER})<!--fig (?P<spec>[^>]*?)-->")
AGGREGATES = {"max": max, "min": min, "sum": sum, "mean": lambda xs: sum(xs) / len(xs)}


def doc_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _lookup(node, keys: list[str]):
    if not keys:
        return node
    key, rest = keys[0], keys[1:]
    if key == "*":
        items = node.values() if isinstance(node, dict) else node
        out = []
        for item in items:
            got = _lookup(item, rest)
            out += got if isinstance(got, list) else [got]
        return out
    return _lookup(node[int(key)] if isinstance(node, list) else node[key], rest)


def figure(spec: str, cache: dict) -> str:
    """The text of the figure ``spec`` (the marker's content)."""
    parts = spec.split()
    file, path, fmt, scale, agg = parts[0], parts[1], "g", 1.0, None
    for p in parts[2:]:
        if p in AGGREGATES:
            agg = p
        elif re.fullmatch(r"x[0-9.eE+-]+", p):
            scale = float(p[1:])
        else:
            fmt = p
    src = ROOT / file if "/" in file else RESULTS / file
    if src not in cache:
        cache[src] = json.loads(src.read_text(encoding="utf-8"))
    value = _lookup(cache[src], path.split("."))
    if isinstance(value, list):
        if agg is None:
            raise ValueError(f"{spec}: the path gives several values; add max|min|mean|sum")
        value = AGGREGATES[agg]([float(v) for v in value])
    value = float(value) * scale
    if fmt.endswith("d"):
        value = int(round(value))
    return format(value, fmt)


def rewrite(text: str, cache: dict) -> tuple[str, list[tuple[str, str, str]]]:
    """``text`` with every marked figure regenerated; and the (spec, old, new) that changed."""
    changed = []

    def sub(m):
        new = figure(m["spec"], cache)
        old = m["value"]
        if "−" in old:  # keep the document's typographic minus
            new = new.replace("-", "−")
        if old != new:
            changed.append((m["spec"], old, new))
        return f"{new}<!--fig {m['spec']}-->"

    return MARK.sub(sub, text), changed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="report differences, change nothing")
    args = ap.parse_args(argv)
    cache: dict = {}
    n = bad = 0
    for path in doc_files():
        text = path.read_text(encoding="utf-8")
        new, changed = rewrite(text, cache)
        n += len(MARK.findall(text))
        for spec, old, value in changed:
            bad += 1
            print(f"{path.relative_to(ROOT)}: {old} -> {value}  ({spec})")
        if changed and not args.check:
            path.write_text(new, encoding="utf-8")
    print(f"{n} figures, {bad} {'differ' if args.check else 'rewritten'}")
    return 1 if args.check and bad else 0


if __name__ == "__main__":
    sys.exit(main())

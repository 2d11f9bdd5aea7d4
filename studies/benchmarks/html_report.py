"""Render the demo's report.html in headless Chromium and save a PNG screenshot.

    python studies/benchmarks/html_report.py [--out sensorless-bench/report.png] [--height 2400]

(the repository's record, studies/benchmarks/results/report.png, is rewritten only by naming it)

Runs the `make demo` pipeline (simulated Panda, LMI model; :func:`sensorless_studies.demo.run_demo`) into a
temporary folder, then `chromium --headless --screenshot` of its report.html: the top of the page,
with the summary and the per-body table (prior, identified value, verdict). Needs a Chromium binary
(Debian: apt-get install chromium); exits 2 saying so when there is none.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="sensorless-bench/report.png", help="PNG to write (default: in the working directory)")
    ap.add_argument("--height", type=int, default=2400, help="window height in pixels (the page's top is shot)")
    args = ap.parse_args()
    browser = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if browser is None:
        print("no Chromium binary on PATH (chromium, chromium-browser, google-chrome)", file=sys.stderr)
        return 2
    from rich.console import Console

    from sensorless_studies.demo import run_demo

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "demo").mkdir()
        run_demo(d / "demo", console=Console(quiet=True))
        page = d / "demo" / "report.html"
        out = Path(args.out).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                        "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={d / 'profile'}",
                        "--hide-scrollbars", f"--screenshot={out}", f"--window-size=1280,{args.height}", page.as_uri()],
                       check=True, capture_output=True, timeout=180)
        size = page.stat().st_size
    print(f"demo report.html ({size} bytes) rendered by {browser}; screenshot {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

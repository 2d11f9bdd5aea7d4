"""Render an identify run's report.html in headless Chromium and save a PNG screenshot.

    python benchmarks/html_report.py [--out benchmarks/results/report.png]

Runs `sensorless identify` (OLS, then validation) on a simulated UR5 log, then
`chromium --headless --screenshot`. Needs a Chromium binary (Debian: apt-get install
chromium); exits 2 saying so when there is none.
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
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "report.png"))
    args = ap.parse_args()
    browser = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if browser is None:
        print("no Chromium binary on PATH (chromium, chromium-browser, google-chrome)", file=sys.stderr)
        return 2
    from typer.testing import CliRunner

    from sensorless.cli import app
    from sensorless.data import write_npz
    from sensorless.excitation import random_fourier
    from sensorless.robot import load_robot
    from sensorless.simulation import perturbed_truth, synthetic_trajectory

    robot = load_robot("ur5")
    truth = perturbed_truth(robot, rng=0)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for name, seed in (("train", 1), ("test", 3)):
            log = synthetic_trajectory(truth, random_fourier(robot, rng=seed).sample(100, 8.0), noise_std=0.05, rng=seed + 1)
            write_npz(log, d / f"{name}.npz")
        res = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(d / "train.npz"), "--validate",
                                       str(d / "test.npz"), "--method", "lmi", "--out", str(d / "run")])
        if res.exit_code != 0:
            print(res.output, file=sys.stderr)
            return 1
        page = d / "run" / "report.html"
        out = Path(args.out).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--screenshot={out}", "--window-size=1200,2400", page.as_uri()],
                       check=True, capture_output=True, timeout=120)
        size = page.stat().st_size
    print(f"{size} bytes of HTML rendered by {browser}; screenshot {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

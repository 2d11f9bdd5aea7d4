"""dVRK PSM payload on the real excitation trajectory, through the CLI (docs/surgical-arm.md §6).

Per payload (100 g, 200 g at ``pitch_end``, CoM 0.35 m along the shaft) and seed: efforts simulated
on the real ``one_results`` trajectory by the model identified on it, AR(1) noise at its per-joint
residual level, a 4 mrad repeat error and the τ2 session offset between the two runs
(:func:`~sensorless_studies.experiments.psm_identification.paired_payload_logs`). The robot model given to
``payload`` is identified on another log (``two_results``)::

    sensorless identify --robot dvrk_psm --data two_results.csv --columns C --rate 200 --lowpass 5.4
        --coulomb-smoothing 0.2 --out m
    sensorless payload --robot dvrk_psm --model m --data load.csv [--no-load noload.csv] [--mode com]
        --columns C --rate 200 --lowpass 5.4 --frame pitch_end --out payload.json

Three estimates per case: paired with the defaults (``--mode auto``, ``--offsets auto``), paired
``--mode com``, unpaired.

    python -m sensorless_studies.benchmarks.psm_payload --wpi ../shared/realdata/dvrk_psm_wpi --out /tmp/psm_payload.json
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["run"]

COLS = ["--columns", "q=0:7;v=7:14;tau=14:21", "--rate", "200", "--lowpass", "5.4"]
COM = (0.0, 0.0, 0.35)
CASES = {"paired": ["--no-load"], "paired_com": ["--no-load", "--mode", "com"], "unpaired": []}


def _cli(args: list) -> None:
    from typer.testing import CliRunner

    from sensorless.cli import app

    r = CliRunner().invoke(app, [str(a) for a in args])
    if r.exit_code != 0:
        raise RuntimeError(f"sensorless {' '.join(map(str, args[:1]))} failed:\n{r.output}")


def run(wpi: Path, work: Path, *, masses=(0.1, 0.2), seeds=(1, 2, 3), console=None) -> dict:
    import pinocchio as pin

    from ..experiments.psm_identification import paired_payload_logs, psm_split_paths, write_psm_csv
    from sensorless.identification import identify
    from sensorless.robots import psm_structure, read_psm_log

    paths = psm_split_paths(wpi)
    s = psm_structure(coulomb_smoothing=0.2)
    one = read_psm_log(paths["train"])
    truth = identify(s, one)
    sigma = np.array(list(truth.diagnostics["residual_sigma"].values()))
    _cli(["identify", "--robot", "dvrk_psm", "--data", paths["test"], *COLS, "--coulomb-smoothing", "0.2", "--out", work / "m"])
    rows = []
    for mass in masses:
        for seed in seeds:
            nl, ld = paired_payload_logs(s, truth.parameters, one, pin.Inertia(mass, np.array(COM), np.zeros((3, 3))),
                                         "pitch_end", noise_std=sigma, seed=seed)
            write_psm_csv(nl, work / "noload.csv")
            write_psm_csv(ld, work / "load.csv")
            row = {"mass_kg": mass, "seed": seed}
            for case, extra in CASES.items():
                extra = [x for a in extra for x in ((a, work / "noload.csv") if a == "--no-load" else (a,))]
                out = work / f"{case}.json"
                _cli(["payload", "--robot", "dvrk_psm", "--model", work / "m", "--data", work / "load.csv", *extra, *COLS,
                      "--frame", "pitch_end", "--out", out, "--force"])
                doc = json.loads(out.read_text())
                row[case] = {"weight_N": doc["weight_N"], "weight_std_N": doc["weight_std_N"],
                             "error_percent": 100 * (doc["weight_N"] / (mass * 9.81) - 1), "mode": doc.get("mode"),
                             "offsets": doc["settings"].get("offsets"), "flagged": doc["flagged_joints"], "com_m": doc["com"]}
            rows.append(row)
            if console is not None:
                console.print(f"{1000 * mass:.0f} g seed {seed}: " + "; ".join(
                    f"{c} {row[c]['weight_N']:.3f} ± {row[c]['weight_std_N']:.3f} N ({row[c]['error_percent']:+.1f} %)" for c in CASES))
    return {"benchmark": "psm_payload", "com_m": list(COM), "frame": "pitch_end", "rows": rows}


def main(argv=None) -> None:
    import argparse
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--wpi", type=Path, default=Path("../shared/realdata/dvrk_psm_wpi"),
                   help="the WPI folder (holding data/psm/...)")
    p.add_argument("--out", type=Path, default=Path("/tmp/sensorless-bench/psm_payload.json"))
    args = p.parse_args(argv)
    from rich.console import Console

    with tempfile.TemporaryDirectory() as tmp:
        res = run(args.wpi, Path(tmp), console=Console())
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2) + "\n")


if __name__ == "__main__":
    main()

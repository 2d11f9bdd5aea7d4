"""Paired runs recorded at different times, with corrupt rows, through the CLI alone (issue 27).

Per seed: a "true" UR10 with Stribeck friction logged with motor currents at a jittery 100 Hz
(:func:`~sensorless_studies.example_data.paired_runs.write_logs`), and two pairs of runs of one trajectory
each, the loaded run starting its excitation ``LAG`` s after the unloaded one and its file
holding 9 corrupt leading rows (values up to 1e154, time running backwards) and a last row cut
after 11 of its 19 fields (:func:`~sensorless_studies.simulation.log_faults.write_faulty_csv`):

* ``cal_unloaded.csv`` / ``cal_loaded.csv``: a known calibration mass at a known CoM on ``tool0``;
* ``pay_unloaded.csv`` / ``pay_loaded.csv``: another trajectory, a payload m ~ U(2, 3) kg at an
  unknown CoM.

Commands (the pairing by time and the lag are defaults; nothing tuned per seed)::

    sensorless drive-gains --robot ur10 --unloaded cal_unloaded.csv --loaded cal_loaded.csv --columns C
        --payload-mass 4 --frame tool0 --com 0.15,0.05,0.05 --skip-bad-rows --out k.json
    sensorless identify --robot ur10 --data pay_unloaded.csv --columns C --gains k.json --out model
    sensorless payload --robot ur10 --model model --data pay_loaded.csv --no-load pay_unloaded.csv
        --frame tool0 --skip-bad-rows --out payload.json

Checked: the gains within 2 %, the payload mass within 3 %, the lags reported within 20 ms of
``LAG``, the corrupt rows dropped (9 at the start, 1 at the end of each loaded file).

    python -m sensorless_studies.benchmarks.paired_logs --seeds 5 --out studies/benchmarks/results/paired_logs.json
    sensorless example paired-runs --out DIR                         # only the logs of seed 0
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..example_data.paired_runs import CAL_COM, CAL_MASS, LAG, write_logs

__all__ = ["run", "one_seed"]

COLUMNS = "q=pos_{joint};v=vel_{joint};tau=i_{joint}"


def _cli(args: list) -> str:
    from typer.testing import CliRunner

    from sensorless.cli import app

    r = CliRunner().invoke(app, [str(a) for a in args])
    if r.exit_code != 0:
        raise RuntimeError(f"sensorless {' '.join(map(str, args))} failed:\n{r.output}")
    return " ".join(r.output.split())


def one_seed(work: Path, seed: int, identify_options: tuple = ()) -> dict:
    """The runs, the three commands and the figures for one seed (files under ``work``)."""
    truth = write_logs(work, seed)
    robot, K, m_pay, com_pay = truth["robot"], truth["gains"], truth["mass"], truth["com"]

    out_k = _cli(["drive-gains", "--robot", "ur10", "--unloaded", work / "cal_unloaded.csv", "--loaded",
                  work / "cal_loaded.csv", "--columns", COLUMNS, "--payload-mass", CAL_MASS, "--frame", "tool0",
                  "--com", ",".join(map(str, CAL_COM)), "--skip-bad-rows", "--out", work / "k.json", "--force"])
    kd = json.loads((work / "k.json").read_text())
    K_id = np.array([kd["gains"][j] for j in robot.actuated_joints])
    _cli(["identify", "--robot", "ur10", "--data", work / "pay_unloaded.csv", "--columns", COLUMNS, "--gains",
          work / "k.json", "--no-plot", *identify_options, "--out", work / "model", "--force"])
    out_p = _cli(["payload", "--robot", "ur10", "--model", work / "model", "--data", work / "pay_loaded.csv",
                  "--no-load", work / "pay_unloaded.csv", "--frame", "tool0", "--skip-bad-rows",
                  "--out", work / "payload.json", "--force"])
    p = json.loads((work / "payload.json").read_text())
    dropped = [kd["settings"]["rows_dropped"].get(str(work / "cal_loaded.csv")),
               p["settings"]["preprocessing"]["rows_dropped"].get(str(work / "pay_loaded.csv"))]
    return {
        "seed": seed, "gains_true": K.tolist(), "gains": K_id.tolist(),
        "gains_relative_error": (K_id / K - 1).tolist(),
        "lag_true": -LAG, "lag_gains": kd["diagnostics"]["alignment"]["lag_s"],
        "lag_payload": p["alignment"][0]["lag_s"],
        "lag_on_console": f"lag {kd['diagnostics']['alignment']['lag_s']:+.3f} s" in out_k
        and f"lag {p['alignment'][0]['lag_s']:+.3f} s" in out_p,
        "payload_true": {"mass": m_pay, "com": list(com_pay)},
        "payload": {"mass": p["mass"], "mass_std": p["mass_std"], "com": p["com"], "mode": p["mode"],
                    "relative_error": (p["mass"] - m_pay) / m_pay},
        "rows_dropped": [[(d["where"], d["rows"]) for d in x["dropped"]] if x else None for x in dropped],
    }


def run(out: Path, *, seeds: int = 5, seed: int = 0, console=None, identify_options: tuple = ()) -> dict:
    """All seeds; the per-seed figures and the acceptance summary."""
    per = []
    for s in range(seed, seed + seeds):
        r = one_seed(Path(out) / f"seed{s}", s, identify_options)
        per.append(r)
        if console is not None:
            console.print(f"seed {s}: gains |err| max {100 * max(map(abs, r['gains_relative_error'])):.2f} %, payload "
                          f"{100 * r['payload']['relative_error']:+.2f} %, lags {r['lag_gains']:+.3f} / "
                          f"{r['lag_payload']:+.3f} s")
    gerr = np.abs([r["gains_relative_error"] for r in per])
    perr = np.abs([r["payload"]["relative_error"] for r in per])
    lags = np.array([[r["lag_gains"], r["lag_payload"]] for r in per])
    return {"seeds": per, "acceptance": {
        "gains_error_max": float(gerr.max()), "gains_within_2pct": bool((gerr <= 0.02).all()),
        "payload_error_max": float(perr.max()), "payload_within_3pct": bool((perr <= 0.03).all()),
        "lag_error_max": float(np.abs(lags + LAG).max()), "lags_within_20ms": bool((np.abs(lags + LAG) <= 0.02).all()),
        "lag_on_console": all(r["lag_on_console"] for r in per),
        "rows_dropped_as_written": all(r["rows_dropped"] == [[("start", 9), ("end", 1)]] * 2 for r in per)}}


def main(argv=None) -> None:
    import argparse
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--out", type=Path, default=Path("sensorless-bench/paired_logs.json"))
    args = p.parse_args(argv)
    from rich.console import Console

    with tempfile.TemporaryDirectory() as tmp:
        res = run(Path(tmp), seeds=args.seeds, console=Console())
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=1))
    print(json.dumps(res["acceptance"], indent=1))


if __name__ == "__main__":
    main()

"""Benchmark of the γ selection (``identify --gamma auto``, the default): exhaustive vs bracketing search.

Cases (generated, so the run needs no files):

* ``ur5-hard``: the UR5 peer benchmark's hard case (600 samples, 5 % noise; the log of
  :func:`~sensorless_studies.benchmarks.peers.peer_case`), ``sensorless identify --robot ur5 --data log.npz``;
* ``talos``: the TALOS walking log of ``sensorless example talos-walk`` (33 bodies, sole wrenches,
  base rows), identified with the documented command (docs/legged-robot.md) but the default γ
  (``--gamma auto``) instead of ``--gamma 1e-2``.

Each case runs ``sensorless identify`` in a fresh process per search (``--gamma-search exhaustive``,
every γ of the grid as before issue 28, the default ``bracket``, and ``closed-form``), interleaved
``repeats`` times; reported per search: end-to-end wall time (process start to exit, best of the repeats),
γ-selection seconds and LMI solves (``result.json`` ``diagnostics.gamma_selection``), the chosen γ,
and whether both searches chose the same γ and wrote the same parameters (largest relative difference).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["CASES", "SEARCHES", "bench_gamma"]

CASES = ("ur5-hard", "talos")
SEARCHES = ("exhaustive", "bracket", "closed-form")
_TALOS_ARGS = ["--robot", "talos", "--data", "walk.npz", "--contact-frames", "left_sole_link,right_sole_link",
               "--contact-dims", "6,6", "--contact-mode", "wrench", "--wrench-offset", "sole", "--joint-terms", "",
               "--imu-frame", "imu_link"]


def _make_case(case: str, where: Path) -> list[str]:
    """Write the case's log into ``where``; the ``identify`` arguments that read it."""
    if case == "ur5-hard":
        from ..benchmarks.peers import peer_case

        t = peer_case("hard", 0).train
        np.savez(where / "log.npz", t=t.t, q=t.q, dq=t.v, tau=t.tau)
        return ["--robot", "ur5", "--data", "log.npz"]
    if case == "talos":
        from ..example_data import talos_walk

        talos_walk.write(where)
        return list(_TALOS_ARGS)
    raise ValueError(f"unknown case '{case}'; choose from {', '.join(CASES)}")


def _run(args: list[str], cwd: Path, out: str) -> dict:
    cmd = [sys.executable, "-c", "from sensorless.cli import main; main()"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd + ["identify", *args, "--out", out, "--force"], cwd=cwd, capture_output=True,
                          text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")})
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1:], "seconds": wall}
    from sensorless.identification.artifact import read_result

    res = read_result(cwd / out)
    sel = res["diagnostics"].get("gamma_selection") or {}
    return {
        "seconds": wall,
        "gamma_selection_seconds": sel.get("seconds"),
        "n_solves": sel.get("n_solves"),
        "n_closed_form": sel.get("n_closed_form"),
        "search": sel.get("search"),
        "gamma_cv": sel.get("gamma"),
        "gamma": res["diagnostics"].get("gamma"),
        "parameters": list(res["parameters"].values()),
    }


def bench_gamma(cases: Sequence[str] = CASES, repeats: int = 1, console=None) -> dict:
    """``{"settings": ..., "results": {case: {search: {...}}}}``, each search compared to "exhaustive"
    (``same_gamma``, ``max_parameter_rel_diff``, ``solves_ratio``, ``gamma_selection_speedup``,
    ``identify_speedup``; module docstring)."""
    out: dict = {"settings": {"cases": list(cases), "repeats": repeats, "cpus": os.cpu_count(),
                              "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
                              "machine": platform.machine(), "python": platform.python_version()},
                 "results": {}}
    for case in cases:
        with tempfile.TemporaryDirectory(prefix=f"sensorless-gamma-{case}-") as tmp:
            where = Path(tmp)
            args = _make_case(case, where)
            runs: dict[str, list[dict]] = {s: [] for s in SEARCHES}
            for _ in range(repeats):
                for search in runs:
                    runs[search].append(_run([*args, "--gamma-search", search], where, f"m_{search}"))
        entry: dict = {}
        for search, rs in runs.items():
            ok = [r for r in rs if "error" not in r]
            if not ok:
                entry[search] = rs[0]
                continue
            best = min(ok, key=lambda r: r["seconds"])
            entry[search] = {**{k: v for k, v in best.items() if k != "parameters"},
                             "gamma_selection_seconds_best": min(r["gamma_selection_seconds"] for r in ok),
                             "seconds_all": [r["seconds"] for r in ok]}
            entry[search]["_params"] = np.asarray(best["parameters"], dtype=float)
        ex = entry["exhaustive"]
        pa = ex.pop("_params", None)
        for search in SEARCHES[1:]:
            new = entry[search]
            pb = new.pop("_params", None)
            if pa is None or pb is None:
                continue
            new["same_gamma"] = ex["gamma"] == new["gamma"] and ex["gamma_cv"] == new["gamma_cv"]
            new["max_parameter_rel_diff"] = float(np.max(np.abs(pa - pb) / np.maximum(np.abs(pa), 1e-12)))
            new["solves_ratio"] = new["n_solves"] / ex["n_solves"]
            new["gamma_selection_speedup"] = ex["gamma_selection_seconds_best"] / new["gamma_selection_seconds_best"]
            new["identify_speedup"] = ex["seconds"] / new["seconds"]
            if console is not None:
                console.print(
                    f"{case} {search} vs exhaustive: solves {new['n_solves']} vs {ex['n_solves']}, γ selection "
                    f"{new['gamma_selection_seconds_best']:.2f} s vs {ex['gamma_selection_seconds_best']:.2f} s, identify "
                    f"{new['seconds']:.2f} s vs {ex['seconds']:.2f} s; γ {new['gamma_cv']:.3g} vs {ex['gamma_cv']:.3g}, "
                    f"parameters max rel diff {new['max_parameter_rel_diff']:.1e}", highlight=False)
        out["results"][case] = entry
    return out

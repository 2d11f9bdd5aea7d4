"""`sensorless benchmark identify-e2e`: the wall time a user waits for `sensorless identify`.

Each run is a fresh process (``python -c "from sensorless.__main__ import main; main()" identify ...``,
this Python, the same ``sys.path``) writing to a new folder; the parent polls for
``OUT/result.json`` every millisecond and records two times from the process start: until
``result.json`` exists (the output folder appears whole, with its figures: it is renamed into
place at once) and until the process exits. Cases, interleaved, best of ``repeats``:

* ``hard``: the UR5 peer benchmark's hard case (600 samples, 5 % noise;
  :func:`~sensorless_studies.benchmarks.peers.peer_case`), the defaults (LMI, γ by cross-validation);
* ``hard_ols``: the same log, ``--method ols``;
* ``long``: a ``long_samples``-sample UR5 Fourier log, the defaults;
* ``hard_no_plot``, ``hard_ols_no_plot``: the first two with ``--no-plot`` (what the figures add);
* ``python``: ``python -c pass`` (the floor of any command on this machine), in the same run.

The CPU seconds of each run (its own and its figure process's) are recorded too: on a loaded
machine they move less than the wall time. ``breakdown``: where the wait goes
(:mod:`~sensorless_studies.benchmarks.identify_breakdown`: import steps, compute steps, and what the
figures add after the fit: the time to result.json minus that with ``--no-plot``).
"""

from __future__ import annotations

import os
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np

from .process_timing import run_timed

__all__ = ["bench_identify_e2e", "GOALS"]

GOALS = {"hard_seconds": "<= 1.5", "hard_ols_seconds": "<= 1.0", "long_seconds": "<= 2.5 (10^5 samples)"}
CLI = "from sensorless.__main__ import main; main()"


def _timed(argv: list[str], env: dict, result: Path | None) -> dict:
    """Seconds from the start of ``argv`` to ``result`` existing (if given) and to its exit, and the CPU
    seconds (user + system) of the process and the children it waited for (less sensitive to load)."""
    r = run_timed(argv, env, result)
    if r["returncode"] != 0:
        raise RuntimeError(f"{' '.join(argv[3:])} exited {r['returncode']}; run it by hand to see why")
    if result is not None and r["result_json"] is None:
        raise RuntimeError(f"{' '.join(argv[3:])} wrote no {result}")
    return {"result_json": r["result_json"], "exit": r["exit"], "cpu": r["cpu"]}


def _logs(folder: Path, long_samples: int) -> dict[str, Path]:
    """The hard case's training log (as issue 28 makes it) and the long UR5 log of ``benchmark speed``
    (5 harmonics at 0.1 Hz, 1 kHz, noise 0.1 N·m, seed 0)."""
    from .long_log import write_ur5_log
    from .peers import peer_case

    train = peer_case("hard", 0).train
    hard = folder / "hard.npz"
    np.savez(hard, t=train.t, q=train.q, dq=train.v, tau=train.tau)
    return {"hard": hard, "long": write_ur5_log(folder / "long.npz", long_samples, accelerations=True)}


def bench_identify_e2e(*, repeats: int = 5, long_samples: int = 100_000, console=None) -> dict:
    """The cases of the module docstring, best of ``repeats`` (and the median), with the load average."""
    def say(msg: str) -> None:
        if console is not None:
            console.print(msg, highlight=False)

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    load_before = os.getloadavg()
    times: dict[str, list[dict]] = {"python": [], "hard": [], "hard_ols": [], "long": [], "hard_no_plot": [],
                                    "hard_ols_no_plot": []}
    with tempfile.TemporaryDirectory(prefix="sensorless-e2e-") as tmp:
        tmp = Path(tmp)
        logs = _logs(tmp, long_samples)
        cases = {"hard": (logs["hard"], []), "hard_ols": (logs["hard"], ["--method", "ols"]), "long": (logs["long"], []),
                 "hard_no_plot": (logs["hard"], ["--no-plot"]), "hard_ols_no_plot": (logs["hard"], ["--method", "ols", "--no-plot"])}
        for k in range(repeats):
            times["python"].append(_timed([sys.executable, "-c", "pass"], env, None))
            for name, (log, extra) in cases.items():
                out = tmp / f"{name}_{k}"
                times[name].append(_timed([sys.executable, "-c", CLI, "identify", "--robot", "ur5", "--data", str(log),
                                           "--out", str(out), *extra], env, out / "result.json"))
            say(f"round {k + 1}/{repeats}: " + ", ".join(f"{n} {v[-1]['exit']:.2f} s" for n, v in times.items()))

    def summary(runs: list[dict]) -> dict:
        out = {}
        for key in ("result_json", "exit", "cpu"):
            v = [r[key] for r in runs if r.get(key) is not None]
            if v:
                out[key] = {"best": min(v), "median": float(np.median(v)), "all": v}
        return out

    res = {
        "what": "sensorless identify wall time from process start (fresh process per run)",
        "commands": {"hard": "sensorless identify --robot ur5 --data hard.npz --out DIR",
                     "hard_ols": "sensorless identify --robot ur5 --data hard.npz --method ols --out DIR",
                     "long": f"sensorless identify --robot ur5 --data <{long_samples}-sample npz> --out DIR",
                     "hard_no_plot": "sensorless identify --robot ur5 --data hard.npz --no-plot --out DIR",
                     "hard_ols_no_plot": "sensorless identify --robot ur5 --data hard.npz --method ols --no-plot --out DIR",
                     "python": "python -c pass"},
        "long_samples": long_samples,
        "repeats": repeats,
        "goals": GOALS,
        "seconds": {name: summary(runs) for name, runs in times.items()},
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "env": {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "SENSORLESS_NATIVE")},
    }
    with tempfile.TemporaryDirectory(prefix="sensorless-e2e-") as tmp:  # where the wait goes (identify_breakdown)
        from .identify_breakdown import LABELS, compute_steps, import_steps

        logs = _logs(Path(tmp), long_samples)
        res["breakdown"] = {"labels": LABELS, "imports": import_steps(repeats, env),
                            "compute": {"hard": compute_steps(logs["hard"], "lmi", env),
                                        "hard_ols": compute_steps(logs["hard"], "ols", env),
                                        "long": compute_steps(logs["long"], "lmi", env)}}
    sec = res["seconds"]
    res["breakdown"]["figures_after_fit"] = {
        n: sec[n]["result_json"]["best"] - sec[f"{n}_no_plot"]["result_json"]["best"] for n in ("hard", "hard_ols")}
    floor = res["seconds"]["python"]["exit"]["best"]
    res["over_python"] = {n: res["seconds"][n]["exit"]["best"] / floor for n in cases}
    s = res["seconds"]
    say(f"best of {repeats} (to result.json / to exit / CPU): "
        + "; ".join(f"{n} {s[n]['result_json']['best']:.2f} / {s[n]['exit']['best']:.2f} / {s[n]['cpu']['best']:.2f} s"
                    for n in cases)
        + f"; python -c pass {floor:.3f} s; load average {load_before[0]:.2f} → {res['load_average_after'][0]:.2f}")
    return res

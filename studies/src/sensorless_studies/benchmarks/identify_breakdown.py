"""Where the wait of `sensorless identify` goes, for `sensorless benchmark identify-e2e`.

* **Imports**, in the order the command makes them: fresh processes importing the CLI, then NumPy
  and Pinocchio (NumPy's f2py and testing deferred, as a command does), then SciPy's linalg/sparse, then Clarabel (the LMI's solver; cvxpy is not
  imported on identify's default path), then the identification modules,
  each set including the previous one; best of ``repeats``; a step's cost is the difference.
* **Compute**: :func:`sensorless.run.identify_run` and ``Run.save`` on the log in one process after
  a first run (its imports and caches done), BLAS on one thread as the CLI has it, the steps timed
  by wrapping the functions that run them; best of 3 runs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

__all__ = ["IMPORT_STEPS", "LABELS", "import_steps", "compute_steps"]

_CLI = "from sensorless.cli import app"
# a command defers NumPy's f2py/testing before SciPy's import (sensorless.cli.startup) as it starts
_NUMPY = _CLI + "; from sensorless.cli.startup import before_scipy; before_scipy(); import numpy, pinocchio"
_SCIPY = _NUMPY + "; import scipy.linalg, scipy.sparse"
_CLARABEL = _SCIPY + "; import clarabel"
_OURS = _CLARABEL + ("; import sensorless.run.pipeline, sensorless.identification.identify, sensorless.identification.gamma,"
                  " sensorless.identification.lmi, sensorless.torque_models, sensorless.cli.identify, sensorless.report.html")
#: (step, the code a fresh process runs: every import up to and including the step)
IMPORT_STEPS = [("python", "pass"), ("cli", _CLI), ("numpy_pinocchio", _NUMPY), ("scipy", _SCIPY), ("clarabel", _CLARABEL),
                ("sensorless", _OURS)]
#: what each step is
LABELS = {"python": "Python itself", "cli": "typer, rich, the command modules", "numpy_pinocchio": "NumPy, Pinocchio",
          "scipy": "SciPy linalg, sparse", "clarabel": "Clarabel, the conic solver",
          "sensorless": "sensorless' identification, data, regressor, report modules",
          "read": "reading, validating, preprocessing", "friction_law": "Coulomb smoothing and Stribeck grids from the log",
          "fold_pass": "one pass over the log: the fit's and the CV folds' equations", "compress": "compression",
          "stribeck": "Stribeck and Coulomb-smoothing choice", "gamma_cv": "γ cross-validation", "final_lmi": "final LMI",
          "ols": "OLS solve", "plausibility": "plausibility, model.urdf's prior masses", "write": "writing the folder"}

#: (module, function, step) wrapped by :func:`compute_steps`
_TIMED = [("sensorless.identification.identify", "_fold_pass", "fold_pass"),
          ("sensorless.identification.identify", "compress", "compress"),
          ("sensorless.identification.identify", "choose_stribeck", "stribeck"),
          ("sensorless.identification.gamma", "cross_validate_gamma", "gamma_cv"),
          ("sensorless.identification.lmi", "solve_lmi", "final_lmi"),
          ("sensorless.identification.identify", "solve_least_squares", "ols"),
          ("sensorless.run.validation", "check_plausible", "plausibility"),
          ("sensorless.run.backend", "load_training", "read"),
          ("sensorless.run.backend", "measure_friction", "friction_law"),
          ("sensorless.run.pipeline", "Run.write", "write")]


def import_steps(repeats: int = 5, env: dict | None = None) -> dict:
    """Seconds per import step (module docstring): ``{step: {"cumulative": s, "step": s}}``."""
    best = {name: float("inf") for name, _ in IMPORT_STEPS}
    for _ in range(repeats):
        for name, code in IMPORT_STEPS:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True, env=env)
            best[name] = min(best[name], time.perf_counter() - t0)
    out, prev = {}, 0.0
    for name, _ in IMPORT_STEPS:
        out[name] = {"cumulative": best[name], "step": best[name] - prev}
        prev = best[name]
    return out


def compute_steps(log: str, method: str = "lmi", env: dict | None = None) -> dict:
    """Seconds per compute step of ``identify --robot ur5 --data LOG --method METHOD --no-plot`` (module
    docstring), in a fresh process: ``{"total": s, "steps": {step: s}}``."""
    code = f"from sensorless_studies.benchmarks.identify_breakdown import _compute; _compute({str(log)!r}, {method!r})"
    env = dict(os.environ if env is None else env, OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", code], check=True, env=env, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def _compute(log: str, method: str) -> None:
    import functools
    import importlib
    import tempfile
    import warnings

    from sensorless.run import RunConfig, identify_run

    warnings.simplefilter("ignore")
    spent: dict[str, float] = {}

    def timed(f, label):
        @functools.wraps(f)
        def g(*a, **k):
            t0 = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - t0
        return g

    for mod, name, label in _TIMED:
        owner = importlib.import_module(mod)
        *path, attr = name.split(".")
        for part in path:
            owner = getattr(owner, part)
        if hasattr(owner, attr):
            setattr(owner, attr, timed(getattr(owner, attr), label))
    cfg = RunConfig.from_options(robot="ur5", data=[log], method=method, plot=False, force=True,
                                 out=os.path.join(tempfile.mkdtemp(prefix="sensorless-breakdown-"), "out"))
    identify_run(cfg).save()
    best = None
    for _ in range(3):
        spent.clear()
        t0 = time.perf_counter()
        identify_run(cfg).save()
        total = time.perf_counter() - t0
        if best is None or total < best["total"]:
            best = {"total": total, "steps": dict(spent)}
    print(json.dumps(best))

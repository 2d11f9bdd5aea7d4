"""Long fuzz run (issue 12): ≥ 10,000 malformed inputs, outcome counts written to JSON.

    python benchmarks/fuzz.py [--scale 1.0] [--seed 0] [--out benchmarks/results/fuzz.json]

Inputs (seeded numpy RNG): NPZ, CSV and HDF5 logs with random keys, shapes, dtypes,
NaN/inf/huge values and truncated or corrupted bytes; ``identify`` on small random
trajectories of a 2-link arm (all four methods, with NaN, spikes, still joints, huge
values); ``sensorless identify`` with random option values. Each input is classified:

* ``typed``   — a SensorlessError (the wanted failure);
* ``ok``      — success with finite, sane values (identify: |π| < 1e6, or a warning said so);
* ``generic`` — any other exception (a bug: the first messages are kept);
* ``garbage`` — success with non-finite or huge values and no warning;
* ``hang``    — over ``--timeout`` seconds (SIGALRM);
* ``crash``   — the worker process died (segfault, abort); counted per lost input.

Batches run in worker subprocesses so a crash cannot take the run down.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

TWO_LINK = (Path(__file__).resolve().parents[1] / "tests" / "data" / "two_link.urdf").read_text()
COUNTS = {"npz": 4000, "csv": 2500, "hdf5": 1500, "identify": 1800, "cli": 250}
BATCH = {"npz": 500, "csv": 500, "hdf5": 500, "identify": 150, "cli": 50}
SPECIAL = [0.0, 1.0, np.nan, np.inf, -np.inf, 1e300, -1e300, 1e-300, 1e30, 1e10, 5e-324, 1e9 + 1]
KEYS = ["times", "positions", "velocities", "accelerations", "torques", "joint_names", "contact", "imu_acc",
        "current", "contact_forces", "base_q"]
DTYPES = ["f8", "f8", "f8", "f4", "i8", "u1", "bool", "c16", "M8[s]", "U3", "O", "f2"]
OPTIONS = {"--rate": None, "--lowpass": None, "--savgol-window": None, "--decimate": None, "--gamma": None,
           "--coulomb-smoothing": None, "--regularization": ["pullback", "bogus", "none", ""],
           "--outliers": ["error", "drop", "keep", "x"], "--method": ["ols", "wls", "svd", "lmi", "ml"],
           "--ellipsoids": ["auto", "none", "kinematic", "?"], "--joint-terms": ["fv,fc", "", "zz", "armature"],
           "--columns": ["q=0:2", "q=pos_{joint}", "bad", "q=9:99", "tau=torques"]}
NUMBERS = ["0", "-1", "nan", "inf", "-inf", "1e300", "1e-300", "abc", "", "3", "11", "2.5", "100", "1e9"]


# ---- input generators -----------------------------------------------------------------------
def _array(rng):
    dtype = str(rng.choice(DTYPES))
    shapes = [(), (0,), (int(rng.integers(0, 40)),), (int(rng.integers(0, 40)), int(rng.integers(0, 5))),
              (int(rng.integers(1, 30)), 2), (3, 2, 2)]
    shape = shapes[int(rng.integers(len(shapes)))]
    if dtype == "O":
        return np.array([None, 1, "a"] * 2, dtype=object)
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 4)
    if x.size and rng.random() < 0.5:
        for _ in range(int(rng.integers(1, 4))):
            x.flat[int(rng.integers(x.size))] = SPECIAL[int(rng.integers(len(SPECIAL)))]
    if dtype == "U3":
        return x.astype(str).astype("U3")
    if dtype == "M8[s]":
        return np.zeros(shape, dtype="M8[s]")
    with np.errstate(all="ignore"):
        return x.astype(dtype)


def _contents(rng):
    keys = list(rng.choice(KEYS, size=int(rng.integers(1, 7)), replace=False))
    if rng.random() < 0.6 and "positions" not in keys:
        keys.append("positions")
    out = {}
    for k in keys:
        if k == "joint_names" and rng.random() < 0.7:
            out[k] = np.array([f"j{i}" for i in range(int(rng.integers(0, 5)))])
        else:
            out[k] = _array(rng)
    if rng.random() < 0.3:  # a nearly valid log with one defect
        n = int(rng.integers(1, 60))
        t = np.arange(n) / 100.0
        out = {"times": t, "positions": rng.normal(size=(n, 2)), "torques": rng.normal(size=(n, 2))}
        k = str(rng.choice(["times", "positions", "torques"]))
        if n:
            out[k] = out[k].copy()
            out[k].flat[int(rng.integers(out[k].size))] = SPECIAL[int(rng.integers(len(SPECIAL)))]
    return out


def _damage(path: Path, rng) -> None:
    mode = int(rng.integers(0, 4))
    if mode == 0:
        return
    data = bytearray(path.read_bytes())
    if not data:
        return
    if mode == 1:
        data = data[: int(rng.integers(0, len(data)))]
    else:
        for i in rng.integers(0, len(data), size=max(1, len(data) // int(rng.integers(10, 200)))):
            data[int(i)] = int(rng.integers(0, 256))
    path.write_bytes(bytes(data))


def make_npz(rng, d: Path) -> Path:
    f = d / "f.npz"
    with open(f, "wb") as fh:
        (np.savez_compressed if rng.random() < 0.5 else np.savez)(fh, **_contents(rng))
    _damage(f, rng)
    return f


def make_hdf5(rng, d: Path) -> Path:
    import h5py

    f = d / "f.h5"
    with h5py.File(f, "w") as h:
        for k, v in _contents(rng).items():
            if v.dtype.kind == "O":
                v = np.zeros(2)
            elif v.dtype.kind == "U":
                v = np.char.encode(v)
            elif v.dtype.kind == "M":
                v = v.astype("i8")
            name = k if rng.random() < 0.8 else f"grp/{k}"
            h[name] = v
        if rng.random() < 0.2:
            h.attrs["joint_names"] = np.array([b"a", b"b"])
    _damage(f, rng)
    return f


def make_csv(rng, d: Path) -> tuple[Path, dict]:
    f = d / "f.csv"
    n, c = int(rng.integers(0, 40)), int(rng.integers(1, 7))
    header = rng.random() < 0.6
    cells = rng.normal(size=(n, c)).astype(object)
    for _ in range(int(rng.integers(0, 4))):
        if n:
            cells[int(rng.integers(n)), int(rng.integers(c))] = rng.choice(
                ["nan", "inf", "1e400", "", "abc", "True", "2020-01-01", "1+2j", "1e300", "-0", "0x10", "1,5"])
    names = ["t"] + [f"q_j{i}" for i in range(c - 1)] if rng.random() < 0.7 else [f"c{i}" for i in range(c)]
    sep = str(rng.choice([",", ";", "\t", " "]))
    lines = ([sep.join(names)] if header else []) + [sep.join(map(str, r)) for r in cells]
    text = "\n".join(lines)
    if rng.random() < 0.2 and text:
        text = text[: int(rng.integers(0, len(text)))]
    f.write_bytes(text.encode("utf-8", "replace") + (bytes(rng.integers(0, 256, 5).tolist()) if rng.random() < 0.1 else b""))
    kw: dict = {"rate": float(rng.choice([100.0, 1e300, 0.0, -5.0, 1e-300]))}
    if not header or rng.random() < 0.3:
        kw["columns"] = {"q": str(rng.choice(["0:2", "1:3", "0:0", "5:9", ":"]))}
    return f, kw


def make_trajectory(rng):
    from sensorless.data import Trajectory

    n = int(rng.integers(2, 400))
    t = np.arange(n) / float(rng.choice([100.0, 1000.0, 1.0]))
    amp = float(10.0 ** rng.uniform(-5, 0.5))
    w = rng.uniform(0.2, 3.0, size=2)
    ph = rng.uniform(0, 6, size=2)
    q = amp * np.sin(np.outer(t, w) + ph)
    v = amp * w * np.cos(np.outer(t, w) + ph)
    a = -amp * w ** 2 * np.sin(np.outer(t, w) + ph)
    tau = rng.normal(scale=float(rng.choice([1e-6, 1e-3, 1.0, 100.0])), size=(n, 2))
    defect = str(rng.choice(["none", "nan", "spike", "const", "still", "huge", "tiny", "tdup", "names"]))
    names = ("j1", "j2")
    if defect == "nan":
        tau[int(rng.integers(n)), int(rng.integers(2))] = np.nan
    elif defect == "spike":
        tau[int(rng.integers(n)), int(rng.integers(2))] = 10.0 ** int(rng.integers(5, 300))
    elif defect == "const":
        q[:] = 0.3
    elif defect == "still":
        q[:, 1], v[:, 1], a[:, 1] = 0.1, 0.0, 0.0
    elif defect == "huge":
        tau *= 10.0 ** int(rng.integers(6, 300))
    elif defect == "tiny":
        tau *= 1e-300
    elif defect == "tdup" and n > 2:
        t[1] = t[0]
    elif defect == "names":
        names = ("j2", "j1") if rng.random() < 0.5 else ("j1", "x")
    method = str(rng.choice(["ols", "wls", "svd", "lmi"]))
    return Trajectory(t=t, q=q, v=v, a=a, tau=tau, joint_names=names), method


def cli_args(rng, robot: Path, log: Path, out: Path) -> list[str]:
    args = ["identify", "--robot", str(robot), "--data", str(log), "--out", str(out)]
    for k in rng.choice(list(OPTIONS), size=int(rng.integers(1, 4)), replace=False):
        vals = OPTIONS[k] or NUMBERS
        args += [str(k), str(vals[int(rng.integers(len(vals)))])]
    return args


# ---- classification ---------------------------------------------------------------------------
class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


def _finite_traj(tr) -> bool:
    from sensorless.data.validation import MAX_ABS_VALUE

    for f in ("t", "q", "v", "a", "tau"):
        val = getattr(tr, f)
        if val is not None and (not np.all(np.isfinite(val)) or (f != "t" and np.any(np.abs(val) > MAX_ABS_VALUE))):
            return False
    return True


def run_case(kind: str, rng, d: Path, robot) -> tuple[str, str]:
    from sensorless.data import read_trajectory
    from sensorless.errors import SensorlessError

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if kind == "npz":
                ok = _finite_traj(read_trajectory(make_npz(rng, d), rate=100.0))
            elif kind == "hdf5":
                ok = _finite_traj(read_trajectory(make_hdf5(rng, d), rate=100.0))
            elif kind == "csv":
                f, kw = make_csv(rng, d)
                ok = _finite_traj(read_trajectory(f, **kw))
            elif kind == "identify":
                from sensorless.identification import identify

                traj, method = make_trajectory(rng)
                res = identify(robot, traj, method=method, gamma=1e-3)
                p = res.parameters
                ok = bool(np.all(np.isfinite(p)) and (np.max(np.abs(p)) < 1e6 or caught))
            else:
                return run_cli(rng, d)
        return ("ok", "") if ok else ("garbage", f"{kind}: success with non-finite/huge values")
    except SensorlessError:
        return "typed", ""
    except Hang:
        raise
    except Exception as exc:  # noqa: BLE001 - this is what we count
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return "generic", f"{kind}: {type(exc).__name__}: {' '.join(str(exc).split())[:200]} @ {tb.filename}:{tb.lineno}"


def run_cli(rng, d: Path) -> tuple[str, str]:
    from typer.testing import CliRunner

    from sensorless.cli import app

    out = d / "o"
    r = CliRunner().invoke(app, cli_args(rng, d / "two.urdf", d / "log.npz", out))
    text = r.output
    if "internal error" in text or "Traceback" in text or r.exit_code not in (0, 2):
        if r.exit_code == 2 and "Usage:" in text:  # typer's own usage error (e.g. "abc" for a float)
            return "typed", ""
        return "generic", f"cli: exit {r.exit_code}: {' '.join(text.split())[:200]}"
    if r.exit_code == 2:
        return "typed", ""
    doc = json.loads((out / "result.json").read_text())
    vals = np.array(list(doc["parameters"].values()), dtype=float)
    return ("ok", "") if np.all(np.isfinite(vals)) else ("garbage", "cli: non-finite parameters")


def worker(kind: str, seed: int, n: int, timeout: float) -> dict:
    import shutil

    from sensorless.robot import load_robot

    counts = {k: 0 for k in ("typed", "ok", "generic", "garbage", "hang")}
    examples: list[str] = []
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "two.urdf").write_text(TWO_LINK)
        robot = load_robot(d / "two.urdf")
        if kind == "cli":
            from sensorless.data import write_npz
            from sensorless.excitation import random_fourier
            from sensorless.simulation import perturbed_truth, synthetic_trajectory

            truth = perturbed_truth(robot, rng=0)
            write_npz(synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(100, 4.0), noise_std=0.05, rng=2),
                      d / "log.npz")
        for i in range(n):
            rng = np.random.default_rng([seed, i])
            shutil.rmtree(d / "o", ignore_errors=True)
            signal.setitimer(signal.ITIMER_REAL, timeout)
            try:
                outcome, msg = run_case(kind, rng, d, robot)
            except Hang:
                outcome, msg = "hang", f"{kind}: case {seed}/{i} exceeded {timeout} s"
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            counts[outcome] += 1
            if msg and len(examples) < 10:
                examples.append(msg)
    return {"counts": counts, "examples": examples}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.0, help="multiply the number of inputs per kind")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per input before it counts as a hang")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/fuzz.json"))
    ap.add_argument("--worker", nargs=3, metavar=("KIND", "SEED", "N"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        kind, seed, n = a.worker[0], int(a.worker[1]), int(a.worker[2])
        print(json.dumps(worker(kind, seed, n, a.timeout)))
        return
    t0 = time.perf_counter()
    total = {k: 0 for k in ("typed", "ok", "generic", "garbage", "hang", "crash")}
    per_kind, examples = {}, []
    for k_i, (kind, count) in enumerate(COUNTS.items()):
        count = int(round(count * a.scale))
        kc = {k: 0 for k in total}
        done = 0
        while done < count:
            n = min(BATCH[kind], count - done)
            seed = a.seed * 1_000_000 + k_i * 10_000 + done
            p = subprocess.run([sys.executable, __file__, "--worker", kind, str(seed), str(n), "--timeout", str(a.timeout)],
                               capture_output=True, text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"})
            if p.returncode != 0:
                kc["crash"] += n  # the batch's inputs are lost with the process
                examples.append(f"{kind}: worker exit {p.returncode}: {p.stderr.strip().splitlines()[-1:]}")
            else:
                res = json.loads(p.stdout.strip().splitlines()[-1])
                for k, v in res["counts"].items():
                    kc[k] += v
                examples += res["examples"][: max(0, 30 - len(examples))]
            done += n
            print(f"{kind}: {done}/{count} {kc}", file=sys.stderr, flush=True)
        per_kind[kind] = kc
        for k in total:
            total[k] += kc[k]
    doc = {
        "n_inputs": sum(total.values()),
        "totals": total,
        "per_kind": per_kind,
        "examples": examples,
        "seed": a.seed,
        "timeout_seconds": a.timeout,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(json.dumps({k: doc[k] for k in ("n_inputs", "totals", "seconds")}))


if __name__ == "__main__":
    main()

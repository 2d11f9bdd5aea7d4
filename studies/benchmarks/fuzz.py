"""Long fuzz run (issues 12 and 26): ≥ 10,000 malformed inputs in ten classes, outcome counts to JSON.

    python studies/benchmarks/fuzz.py [--classes npz,csv,...] [--scale 1.0] [--seed 0] [--jobs 2] [--out PATH]

Classes (default counts at --scale 1): ``npz`` 4000, ``csv`` 2500, ``hdf5`` 1500 (logs with random
keys, shapes, dtypes, NaN/inf/huge values, truncated or corrupted bytes), ``identify`` 1800 (small
random trajectories of a 2-link arm, all methods), ``cli`` 250 (random ``identify`` option values),
and (issue 26, ``fuzz_classes/``) ``outputs`` 1500, ``descriptions`` 1000, ``oversize`` 400, (issue 41) ``service`` 400,
``model_folder`` 400, ``containers`` 600, ``numerics`` 600 (issue 23: constant, zero, dead,
≥ 100× scaled, permuted and sign-flipped torque channels), ``formats`` 800 (issue 27: MATLAB v7.3/v5
files, per-signal text folders and ``.dat`` logs with tick columns, ``--skip-bad-rows`` and ``--trim``). Each input is classified:

* ``typed``   — a SensorlessError (the wanted failure);
* ``ok``      — success with finite, sane values (identify: |π| < 1e6, or a warning said so);
* ``generic`` — any other exception, "internal error", exit 3 (a bug: the first messages are kept);
* ``garbage`` — success with non-finite, huge or silently truncated values and no warning;
* ``hang``    — over ``--timeout`` seconds (SIGALRM), or a worker silent for ``--timeout`` + 15 s;
* ``crash``   — the worker process died (segfault, abort); one input, the rest go on in a new worker;
* ``data_loss``, ``executed``, ``disclosure`` — see ``fuzz_classes/common.py``.

Inputs run in worker subprocesses (an address-space limit, ``--max-memory-gb``, keeps memory
bombs from taking the machine) that print one JSON line per input. The summary goes to ``--out``
(default ``$XDG_CACHE_HOME/sensorless-bench/fuzz.json``, else ``/tmp/sensorless-bench/fuzz.json``).
"""

from __future__ import annotations

import argparse
import contextlib
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_classes import NEW, module as fuzz_module  # noqa: E402
from fuzz_classes.common import OUTCOMES, Hang  # noqa: E402

TWO_LINK = (Path(__file__).resolve().parents[2] / "tests" / "data" / "two_link.urdf").read_text()
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


def _setup_old(kind: str, d: Path):
    from sensorless.robot import load_robot

    (d / "two.urdf").write_text(TWO_LINK)
    robot = load_robot(d / "two.urdf")
    if kind == "cli":
        from sensorless.data import write_npz
        from sensorless.excitation import random_fourier
        from sensorless.testing import perturbed_truth, synthetic_trajectory

        truth = perturbed_truth(robot, rng=0)
        write_npz(synthetic_trajectory(truth, random_fourier(robot, rng=1).sample(100, 4.0), noise_std=0.05, rng=2),
                  d / "log.npz")
    return robot


def worker(kind: str, seed: int, start: int, n: int, timeout: float, d: Path, scale: float, emit=print) -> None:
    """Run inputs ``start .. start+n-1`` of ``kind`` in folder ``d``; one JSON line per input."""
    import shutil

    fired = []

    def alarm(signum, frame):
        fired.append(1)
        raise Hang()

    signal.signal(signal.SIGALRM, alarm)
    new = kind in NEW
    mod = fuzz_module(kind) if new else None
    ctx = mod.setup(d, scale) if new else _setup_old(kind, d)
    try:
        for i in range(start, start + n):
            rng = np.random.default_rng([seed, i])
            for junk in ("o", "case"):
                shutil.rmtree(d / junk, ignore_errors=True)
            fired.clear()
            signal.setitimer(signal.ITIMER_REAL, timeout)
            try:
                outcome, msg = mod.case(rng, d, ctx) if new else run_case(kind, rng, d, ctx)
            except Hang:
                outcome, msg = "hang", ""
            except Exception as exc:  # noqa: BLE001 - a bug of the harness itself: say so, do not hide it
                outcome, msg = "generic", f"{kind}: harness: {type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            if fired:  # a timeout, even when the code under test caught it and raised something else
                outcome, msg = "hang", f"{kind}: case {seed}/{i} exceeded {timeout} s"
            emit(json.dumps({"i": i, "o": outcome, "m": msg}), flush=True)
    finally:
        if new and hasattr(mod, "teardown"):
            mod.teardown(ctx)


def _unmount_under(d: Path) -> None:
    try:
        mounts = [line.split()[1] for line in Path("/proc/mounts").read_text().splitlines()]
    except OSError:
        return
    for m in mounts:
        if m.startswith(str(d)):
            subprocess.run(["umount", "-l", m], capture_output=True)


def run_batch(kind: str, seed: int, start: int, n: int, a) -> tuple[dict, list, dict]:
    """Inputs ``start .. start+n-1`` in worker processes; a worker that dies or stops answering for
    ``timeout + 15`` s costs one input (``crash`` / ``hang``) and the rest continue in a new worker."""
    import queue
    import shutil
    import threading

    counts, examples, notes = {k: 0 for k in OUTCOMES}, [], {}
    end = start + n
    while start < end:
        d = Path(tempfile.mkdtemp(prefix=f"fuzz-{kind}-", dir=a.tmp))
        env = {**os.environ, "PYTHONWARNINGS": "ignore", "OPENBLAS_NUM_THREADS": "1", "TMPDIR": str(d)}
        p = subprocess.Popen([sys.executable, __file__, "--worker", kind, str(seed), str(start), str(end - start),
                              "--timeout", str(a.timeout), "--scale", str(a.scale), "--max-memory-gb",
                              str(a.max_memory_gb), "--tmp", str(d)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env=env, start_new_session=True)
        lines: queue.Queue = queue.Queue()
        threading.Thread(target=lambda: [lines.put(x) for x in p.stdout] + [lines.put(None)], daemon=True).start()
        err: list = []
        threading.Thread(target=lambda: err.extend(p.stderr), daemon=True).start()
        lost, first = None, True
        while start < end:
            try:  # the first answer also waits for the worker's setup
                line = lines.get(timeout=a.timeout + 15 + (180 if first else 0))
                first = False
            except queue.Empty:
                lost = "hang"
                break
            if line is None:
                lost = "crash"
                break
            if not line.startswith("{"):
                continue
            r = json.loads(line)
            if r["o"] == "skipped":
                notes["skipped"] = notes.get("skipped", 0) + 1
            else:
                counts[r["o"]] += 1
            if r["m"] and len(examples) < 10:
                examples.append(r["m"])
            start = r["i"] + 1
        if lost:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        if lost:
            counts[lost] += 1
            tail = "".join(err).strip().splitlines()[-1:] if lost == "crash" else []
            examples.append(f"{kind}: input {seed}/{start}: worker {'stopped answering' if lost == 'hang' else 'died'} "
                            f"(exit {p.returncode}) {tail}"[:300])
            start += 1
        _unmount_under(d)
        shutil.rmtree(d, ignore_errors=True)
    return counts, examples, notes


def default_out() -> Path:
    base = os.environ.get("XDG_CACHE_HOME")
    return (Path(base) if base else Path(tempfile.gettempdir())) / "sensorless-bench" / "fuzz.json"


def main() -> None:
    from concurrent.futures import ThreadPoolExecutor

    kinds = {**{k: (COUNTS[k], BATCH[k]) for k in COUNTS}, **NEW}
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.0, help="multiply the number of inputs per class")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per input before it counts as a hang")
    ap.add_argument("--classes", default=",".join(kinds), help=f"comma-separated subset of {','.join(kinds)}")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes at a time")
    ap.add_argument("--max-memory-gb", type=float, default=4.0, help="address-space limit of each worker (RLIMIT_AS)")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON summary (default {default_out()})")
    ap.add_argument("--tmp", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--worker", nargs=4, metavar=("KIND", "SEED", "START", "N"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        import resource

        if a.max_memory_gb > 0:
            lim = int(a.max_memory_gb * 2 ** 30)
            resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
        kind, seed, start, n = a.worker[0], int(a.worker[1]), int(a.worker[2]), int(a.worker[3])
        worker(kind, seed, start, n, a.timeout, a.tmp, a.scale)
        return
    chosen = [k.strip() for k in a.classes.split(",") if k.strip()]
    unknown = sorted(set(chosen) - set(kinds))
    if unknown:
        ap.error(f"unknown class(es) {unknown}; choose from {sorted(kinds)}")
    out = a.out or default_out()
    a.tmp = Path(tempfile.mkdtemp(prefix="sensorless-fuzz-"))
    t0 = time.perf_counter()
    total = {k: 0 for k in OUTCOMES}
    per_kind, examples, notes, seconds = {}, [], {}, {}
    for kind in chosen:
        count, batch = kinds[kind]
        count = int(round(count * a.scale))
        seed = a.seed * 1000 + list(kinds).index(kind)
        t1 = time.perf_counter()
        with ThreadPoolExecutor(max(1, a.jobs)) as pool:
            results = list(pool.map(lambda s: run_batch(kind, seed, s, min(batch, count - s), a), range(0, count, batch)))
        kc, kn = {k: 0 for k in OUTCOMES}, {}
        for c, ex, nt in results:
            for k, v in c.items():
                kc[k] += v
            for k, v in nt.items():
                kn[k] = kn.get(k, 0) + v
            examples += ex[: max(0, 60 - len(examples))]
        per_kind[kind], notes[kind], seconds[kind] = kc, kn, round(time.perf_counter() - t1, 1)
        for k in total:
            total[k] += kc[k]
        print(f"{kind}: {sum(kc.values())} inputs {kc} {kn or ''} {seconds[kind]} s", file=sys.stderr, flush=True)
    doc = {
        "n_inputs": sum(total.values()),
        "totals": total,
        "per_kind": per_kind,
        "notes": notes,
        "examples": examples,
        "classes": chosen,
        "scale": a.scale,
        "seed": a.seed,
        "timeout_seconds": a.timeout,
        "seconds_per_kind": seconds,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")
    import shutil

    _unmount_under(a.tmp)
    shutil.rmtree(a.tmp, ignore_errors=True)
    print(json.dumps({k: doc[k] for k in ("n_inputs", "totals", "seconds")}))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

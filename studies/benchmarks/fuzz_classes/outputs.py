"""Class ``outputs``: output safety (issue 26, items 0, 1, 4).

Most cases call :func:`sensorless.io.atomic_output_dir` in-process on a random target: a previous
sensorless output (intact, with a user-edited listed file, a user-made empty folder or an extra
file), a user folder, a folder holding an input, a user file, a FIFO, a private device node equal
to /dev/null (never the real one), a read-only mount, missing parents, a full disk (a small tmpfs,
root only; otherwise counted under ``notes.skipped``), with or without ``force``, succeeding or
failing inside the block. A bounded share runs real commands (predict / estimate-force / payload /
identify / monitor via CliRunner) onto such targets, and a share kills (SIGKILL / SIGTERM at a
random delay) a child process doing a ``force`` replacement, optionally with slow renames and a
busy second thread. ``data_loss`` when a protected path changed, or the output is neither the
intact previous one nor a complete new one (after a next command touching it, for journaled
recovery).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from .common import cli, cli_outcome, complete_output, digest, make_device, one_line, setup_model

TARGETS = ["output", "edited", "emptydir", "extra", "user_dir", "input_inside", "user_file", "fifo", "device",
           "readonly", "missing_parent", "disk_full"]

CHILD = r"""
import os, sys, time, threading, random
from pathlib import Path
from sensorless.io import atomic_output_dir
out, n, pause, slow, thread = Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5] == "1"
if slow:
    real = os.rename
    def rename(a, b, *k, **kw):
        real(a, b, *k, **kw); time.sleep(slow)
    os.rename = rename
if thread:
    threading.Thread(target=lambda: [sum(range(1000)) for _ in iter(int, 1)], daemon=True).start()
print("R", flush=True)
with atomic_output_dir(out, force=True, command={"name": "fuzz-kill"}) as tmp:
    for i in range(n):
        (tmp / f"f{i}.txt").write_text("new %d" % i)
        time.sleep(pause)
"""


def setup(d: Path, scale: float) -> dict:
    ctx = setup_model(d)
    full = d / "full"
    full.mkdir()
    ro = d / "ro"
    ro.mkdir()
    ctx["mounted"] = []
    if os.geteuid() == 0:
        for where, opts in ((full, "size=96k"), (ro, "size=64k,ro")):
            if subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(where)], capture_output=True).returncode == 0:
                ctx["mounted"].append(where)
    else:
        os.chmod(ro, 0o555)
    return ctx


def teardown(ctx: dict) -> None:
    for m in ctx.get("mounted", []):
        subprocess.run(["umount", "-l", str(m)], capture_output=True)


def _write_output(out: Path, tag: str, n: int = 3, size: int = 10) -> None:
    from sensorless.io import atomic_output_dir

    with atomic_output_dir(out, force=out.exists(), command={"name": "fuzz"}) as tmp:
        for i in range(n):
            (tmp / f"f{i}.txt").write_text(f"{tag} {i} " + "x" * size)


def _prepare(rng, d: Path, ctx: dict) -> tuple[Path, dict, list, str]:
    """(out, protected {path: digest}, inputs, target kind); ``out`` set up as the target kind."""
    kind = TARGETS[int(rng.integers(len(TARGETS)))]
    case = d / "case"
    case.mkdir()
    out = case / "out"
    inputs: list = []
    if kind in ("output", "edited", "emptydir", "extra"):
        _write_output(out, "old", n=int(rng.integers(1, 6)))
        if kind == "edited":
            (out / "f0.txt").write_text("the user's edit")
        elif kind == "emptydir":
            (out / "notes").mkdir()
        elif kind == "extra":
            (out / "mine.txt").write_text("user data")
    elif kind == "user_dir":
        out.mkdir()
        (out / "thesis.tex").write_text("user data")
    elif kind == "input_inside":
        _write_output(out, "old") if rng.random() < 0.5 else out.mkdir()
        (out / "log.npz").write_bytes(b"input")
        inputs = [out / "log.npz"]
    elif kind == "user_file":
        out.write_text("user file")
    elif kind == "fifo":
        os.mkfifo(out)
    elif kind == "device" and not make_device(out):
        return out, {}, [], "skipped"
    elif kind == "readonly":
        if ctx["ro"] is None:
            return out, {}, [], "skipped"
        out = ctx["ro"] / f"out{int(rng.integers(1000))}"
    elif kind == "missing_parent":
        out = case / "a" / "b" / "out"
    elif kind == "disk_full":
        if ctx["full"] is None:
            return out, {}, [], "skipped"
        for p in ctx["full"].iterdir():
            subprocess.run(["rm", "-rf", str(p)])
        out = ctx["full"] / "out"
        _write_output(out, "old", n=2, size=int(rng.integers(10, 40_000)))
    protected = {} if kind in ("output", "disk_full", "missing_parent") else {out: digest(out)}
    protected.update({p: digest(p) for p in inputs})
    return out, protected, inputs, kind


def _judge(out: Path, before: str, protected: dict, kind: str, replaced_ok: bool) -> str | None:
    """'data_loss' or None after an in-process or CLI case."""
    for p, dg in protected.items():
        if digest(p) != dg and not (p == out and replaced_ok and kind == "output"):
            return "data_loss"
    if before.startswith("dir:") and digest(out) != before and not complete_output(out):
        return "data_loss"
    return None


def inprocess_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.errors import SensorlessError
    from sensorless.io import atomic_output_dir

    out, protected, inputs, kind = _prepare(rng, d, ctx)
    if kind == "skipped":
        return "skipped", ""
    before = digest(out)
    force, fail = bool(rng.random() < 0.6), bool(rng.random() < 0.2)
    n_files, size = int(rng.integers(1, 5)), int(10 ** rng.uniform(1, 5.3))
    outcome, msg = "ok", ""
    try:
        with atomic_output_dir(out, force=force, inputs=inputs, command={"name": "fuzz"}) as tmp:
            for i in range(n_files):
                (tmp / f"g{i}.txt").write_text("new " + "y" * size)
            if fail:
                raise KeyError("fuzz: failure inside the block")
        if not complete_output(out):
            outcome, msg = "data_loss", f"outputs/{kind}: success but {out.name} is not a complete output"
    except SensorlessError:
        outcome = "typed"
    except KeyError as exc:
        outcome = "typed" if "fuzz" in str(exc) and digest(out) == before else "data_loss"
    except Exception as exc:  # noqa: BLE001
        outcome, msg = "generic", f"outputs/{kind}: {type(exc).__name__}: {one_line(exc)}"
    if kind in ("edited", "emptydir") and outcome == "ok":
        outcome, msg = "data_loss", f"outputs/{kind}: force replacement deleted the user's {kind} content"
    loss = _judge(out, before, protected, kind, outcome == "ok")
    if loss:
        return loss, f"outputs/{kind} force={force} fail={fail}: {out.name} changed (was {before[:9]}, now {digest(out)[:9]})"
    return outcome, msg


def cli_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    model, log, robot = ctx["model"], ctx["log"], ctx["robot_file"]
    case = d / "case"
    case.mkdir()
    m = case / "model"
    subprocess.run(["cp", "-a", str(model), str(m)], check=True)
    what = str(rng.choice(["user_file", "result_json", "fifo", "device", "disk_full", "input_dir", "output_noforce"]))
    cmd = str(rng.choice(["predict", "estimate-force", "payload", "identify", "monitor"]))
    force = bool(rng.random() < 0.5)
    file_out = cmd in ("predict", "estimate-force", "payload")
    if what == "user_file":
        out = case / ("x.json" if cmd == "payload" else "x.npz")
        out.write_text("user file")
    elif what == "result_json":
        out = m / "result.json" if file_out else m
    elif what == "fifo":
        out = case / "fifo"
        os.mkfifo(out)
    elif what == "device":
        out = case / "null"
        if not make_device(out):
            return "skipped", ""
    elif what == "disk_full":
        if ctx["full"] is None:
            return "skipped", ""
        for p in ctx["full"].iterdir():
            subprocess.run(["rm", "-rf", str(p)])
        (ctx["full"] / "ballast").write_bytes(b"\0" * int(rng.integers(0, 90_000)))
        out = ctx["full"] / ("o.json" if cmd == "payload" else "o.npz" if file_out else "o")
    elif what == "input_dir":
        out = case / "logs"
        out.mkdir()
        log2 = out / "log.npz"
        subprocess.run(["cp", str(log), str(log2)], check=True)
        log = log2
    else:  # a previous output (a file, or a sensorless output folder) without --force
        out = case / ("o.json" if cmd == "payload" else "o.npz" if file_out else "o")
        if file_out:
            out.write_bytes(b"previous output")
        else:
            _write_output(out, "old")
        force = False
    protected = {m: digest(m), log: digest(log)}
    if what != "disk_full":
        protected[out] = digest(out)
    # --force replaces a file the user names (as `cp -f` does), and identify (which reads no model) may
    # replace a previous sensorless output folder: not data loss, as long as the result is complete
    replaceable = force and cmd in ("payload", "identify", "monitor") and (
        what == "user_file" or (what == "result_json" and cmd == "identify"))
    if replaceable:
        protected.pop(out, None)
        if cmd == "identify":
            protected.pop(m, None)
    before = digest(out)
    base = ["--robot", robot, "--data", log, "--out", out]
    args = {"predict": ["predict", *base, "--model", m],
            "estimate-force": ["estimate-force", *base, "--model", m, "--frame", "l2"],
            "payload": ["payload", *base, "--model", m, "--frame", "l2", "--n-boot", "0"],
            "identify": ["identify", *base, "--method", "ols", "--no-plot", "--joint-terms", "fv,fc"],
            "monitor": ["monitor", *base, "--model", m]}[cmd]
    if force and cmd in ("payload", "identify", "monitor"):
        args.append("--force")
    r = cli(args)
    outcome, msg = cli_outcome(r, f"outputs/cli {cmd} {what} force={force}")
    for p, dg in protected.items():
        if digest(p) != dg:
            return "data_loss", f"outputs/cli {cmd} --out {what} force={force}: {p.name} changed (exit {r.exit_code})"
    if before.startswith("dir:") and digest(out) != before and not complete_output(out):
        return "data_loss", f"outputs/cli {cmd} {what}: output folder incomplete"
    return outcome or "ok", msg


def kill_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.io import atomic_output_dir

    case = d / "case"
    case.mkdir()
    out = case / "out"
    _write_output(out, "old", n=int(rng.integers(1, 200)))
    old = digest(out)
    sig = signal.SIGKILL if rng.random() < 0.5 else signal.SIGTERM
    slow = float(rng.choice([0.0, 0.02, 0.05]))
    pause = float(rng.choice([0.0, 0.002, 0.01]))
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(out), str(int(rng.integers(1, 20))), str(pause), str(slow),
                          "1" if rng.random() < 0.5 else "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        p.stdout.readline()  # "R": imports done
        time.sleep(float(rng.uniform(0.0, 0.25)))
        p.send_signal(sig)
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()

    def fine() -> bool:
        if digest(out) == old:
            return True
        if not complete_output(out):
            return False
        return all(f.read_text().startswith("new") for f in out.glob("f*.txt"))

    if fine():
        return "ok", ""
    try:  # a next command touching OUT (without --force) may complete a journaled replacement
        with atomic_output_dir(out, force=False):
            raise KeyError("fuzz: next command writes nothing")
    except Exception:  # noqa: BLE001 - only its effect on OUT matters
        pass
    if fine():
        return "ok", ""
    left = sorted(x.name for x in case.iterdir())
    return "data_loss", f"outputs/kill {signal.Signals(sig).name} slow={slow}: OUT neither old nor complete new; left {left[:4]}"


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    ctx.setdefault("full", ctx["mounted"][0] if d / "full" in ctx.get("mounted", []) else None)
    ctx.setdefault("ro", (d / "ro") if (d / "ro" in ctx.get("mounted", []) or os.geteuid() != 0) else None)
    u = rng.random()
    if u < 0.08:
        return kill_case(rng, d, ctx)
    if u < 0.2:
        return cli_case(rng, d, ctx)
    return inprocess_case(rng, d, ctx)

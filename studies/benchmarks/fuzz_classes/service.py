"""Class ``service`` (issue 41, "safe as a service"): the surfaces the earlier classes did not reach.

Each case draws one attack: a symlink or FIFO planted as the lock or journal of an output, user
folders with the names of hidden temporaries next to it, a planted journal naming a tree elsewhere
(``paths``); a TOML that gives consent or overrides itself or names the secret as a log, gains or
weights (``toml``); a stream of records with non-finite, 1e300 or out-of-range values, or a ``seq``
restart (``stream``); joint names with rich markup or control characters (``markup``); the same log
given twice by path, link, hard link or copy (``duplicates``).

``data_loss``: a planted target, user folder or the other folder's output changed. ``disclosure``: the
secret in an error or output. ``garbage``: the stream flags more samples than the clean stream plus the
bad ones (the observer was fed a bad sample), a restart is not reported, or a duplicated log is read
twice without a warning. ``typed``/``ok``: refused with a one-line error, or handled.
"""

from __future__ import annotations

import os
import shutil
import warnings
from pathlib import Path

import numpy as np

from .common import cli, cli_outcome, digest, leaked, one_line, plant_secret, setup_model

KINDS = ("paths", "toml", "stream", "markup", "duplicates")


def setup(d: Path, scale: float) -> dict:
    from sensorless.estimation.momentum import MomentumDynamics
    from sensorless.estimation.monitoring import MonitorSettings, monitor_log
    from sensorless.realtime import StreamMonitor, StreamThresholds
    from sensorless.regressor import ModelStructure

    ctx = setup_model(d)
    ctx["secret"], ctx["secret_text"] = plant_secret(d)
    traj, robot = ctx["traj"], ctx["robot"]
    dyn = MomentumDynamics(ModelStructure(robot, joint_terms=()), robot.inertial_parameters())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        th = StreamThresholds.from_result(monitor_log(dyn, traj, MonitorSettings(quiet="0:1")))
    ctx["dyn"], ctx["th"] = dyn, th
    sm = StreamMonitor(dyn, th)
    ctx["clean_flags"] = np.array([sm.step(i, traj.t[i], traj.q[i], traj.v[i], traj.tau[i])[-1]
                                   for i in range(len(traj))])
    ctx["make_monitor"] = lambda: StreamMonitor(dyn, th)
    return ctx


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    kind = str(rng.choice(KINDS))
    work = d / f"case-{rng.integers(1 << 40):x}"
    work.mkdir()
    try:
        return globals()[f"_{kind}"](rng, work, ctx)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _paths(rng, w: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.errors import SensorlessError
    from sensorless.io import atomic_output_dir
    from sensorless.outdir import recover_output

    victim = w / "victim.txt"
    victim.write_text("precious")
    out = w / "run"
    with atomic_output_dir(out) as tmp:
        (tmp / "a.txt").write_text("old")
    other = w / "other"
    other.mkdir()
    theirs = other / f".run.old-{rng.integers(1 << 20)}-{rng.bytes(6).hex()}"
    with atomic_output_dir(theirs) as tmp:
        (tmp / "b.txt").write_text("theirs")
    planted = []
    for name in rng.choice([".run.lock", ".run.journal", ".run.tmp-user", ".run.old-notes",
                            f".run.tmp-999999-{rng.bytes(6).hex()}", f".run.old-{rng.integers(1 << 20)}"],
                           size=int(rng.integers(1, 4)), replace=False):
        p = w / str(name)
        how = str(rng.choice(["symlink", "fifo", "folder", "journal"]))
        if how == "symlink":
            p.symlink_to(victim)
        elif how == "fifo":
            os.mkfifo(p)
        elif how == "journal":
            p.write_text('{"out": "run", "old": "../other/%s", "new": "../other/%s"}' % (theirs.name, theirs.name))
        else:
            p.mkdir()
            (p / "notes.txt").write_text("user data")
        planted.append(p)
    before = {p: digest(p) for p in [victim, theirs, *planted]}
    try:
        recover_output(out)
        with atomic_output_dir(out, force=True) as tmp:
            (tmp / "a.txt").write_text("new")
        outcome = "ok"
    except SensorlessError:
        outcome = "typed"
    except Exception as exc:  # noqa: BLE001
        return "generic", f"service/paths: {type(exc).__name__}: {one_line(exc)}"
    changed = [p.name for p, h in before.items() if digest(p) != h]
    if changed:
        return "data_loss", f"service/paths: changed {changed}"
    return outcome, ""


def _toml(rng, w: Path, ctx: dict) -> tuple[str, str]:
    secret = ctx["secret"]
    lines = [f'robot = "{ctx["robot_file"]}"', f'out = "{w / "o"}"']
    what = str(rng.choice(["override", "data", "gains", "weights"]))
    if what == "override":
        lines += [f'data = ["{ctx["log"]}"]', f'{rng.choice(["force", "allow_hdf5_external", "accept_implausible", "accept_implausible_gains", "trust_xacro"])} = true']
    elif what == "data":
        lines += [f'data = ["{secret}"]']
    else:
        lines += [f'data = ["{ctx["log"]}"]', f'{what} = "{secret}"']
    cfg = w / "c.toml"
    cfg.write_text("\n".join(lines) + "\n")
    r = cli(["identify", "--config", cfg, "--method", "ols", "--no-plot"])
    if leaked(ctx["secret_text"], r.output, files=[w / "o"]):
        return "disclosure", f"service/toml {what}: the secret was shown or written"
    bad, msg = cli_outcome(r, f"service/toml {what}")
    if bad:
        return bad, msg
    if what == "override" and r.exit_code == 0:
        return "garbage", "service/toml: an override was taken from the file"
    return "typed" if r.exit_code else "ok", ""


def _stream(rng, w: Path, ctx: dict) -> tuple[str, str]:
    import io
    import sys

    from sensorless.errors import SensorlessError
    from sensorless.realtime.transport import Endpoint, run_stream

    traj = ctx["traj"]
    sm = ctx["make_monitor"]()
    q, v, tau, seq = traj.q.copy(), traj.v.copy(), traj.tau.copy(), np.arange(len(traj))
    bad = rng.choice(len(traj), size=int(rng.integers(1, 4)), replace=False)
    restart = rng.random() < 0.3
    for i in bad:
        arr = [q, v, tau][int(rng.integers(3))]
        arr[i, int(rng.integers(arr.shape[1]))] = float(rng.choice([1e300, -1e300, np.nan, np.inf, 1e7]))
    t = traj.t.copy()
    if restart:
        k = int(rng.integers(len(traj) // 3, 2 * len(traj) // 3))
        seq = np.concatenate([seq[:k], np.arange(len(traj) - k)])
    text = b"".join(sm.layout.encode_input(int(s), t[i], q[i], v[i], tau[i], "csv") for i, s in enumerate(seq))
    old_in, old_err, old_write = sys.stdin, sys.stderr, os.write
    sys.stdin, sys.stderr = io.TextIOWrapper(io.BytesIO(text)), io.StringIO()  # the warnings go to stderr
    out: list = []
    os.write = lambda fd, data: (out.append(bytes(data)), len(data))[1] if fd == 1 else old_write(fd, data)
    try:
        stats = run_stream(sm, Endpoint("stdio"), Endpoint("stdio"), "csv", skip_bad=True)
        err = sys.stderr.getvalue()
    except SensorlessError:
        return "typed", ""
    except Exception as exc:  # noqa: BLE001
        return "generic", f"service/stream: {type(exc).__name__}: {one_line(exc)}"
    finally:
        sys.stdin, sys.stderr, os.write = old_in, old_err, old_write
    if restart and "restarted" not in err:
        return "garbage", "service/stream: a seq restart was not reported while streaming"
    flagged = stats.contact_samples + getattr(stats, "out_of_range", 0)
    if not restart and flagged > ctx["clean_flags"].sum() + len(bad):
        return "garbage", (f"service/stream: {flagged} samples flagged against {int(ctx['clean_flags'].sum())} "
                           f"clean + {len(bad)} bad")
    return "ok", ""


def _markup(rng, w: Path, ctx: dict) -> tuple[str, str]:
    names = ["a[/]b", "[bold red]x", "[link=file:///etc/passwd]y[/link]", "j\\[z", "[/]"]
    text = ctx["robot_file"].read_text()
    robot = ctx["robot"]
    picked = rng.choice(names, size=len(robot.joint_names), replace=False)
    for old, new in zip(robot.joint_names, picked):
        text = text.replace(f'name="{old}"', f'name="{new}"')
    urdf = w / "mk.urdf"
    urdf.write_text(text)
    from sensorless.data import write_npz

    log = write_npz(ctx["traj"].with_(joint_names=tuple(str(p) for p in picked)), w / "mk.npz")
    r = cli(["identify", "--robot", urdf, "--data", log, "--out", w / "o", "--method", "ols", "--no-plot",
             "--joint-terms", "fv,fc"])
    bad, msg = cli_outcome(r, "service/markup")
    return (bad, msg) if bad else ("typed" if r.exit_code else "ok", "")


def _duplicates(rng, w: Path, ctx: dict) -> tuple[str, str]:
    log = ctx["log"]
    how = str(rng.choice(["path", "symlink", "hardlink", "copy"]))
    twin = w / "twin.npz"
    if how == "symlink":
        twin.symlink_to(log)
    elif how == "hardlink":
        try:
            os.link(log, twin)
        except OSError:
            shutil.copy(log, twin)
    elif how == "copy":
        shutil.copy(log, twin)
    else:
        twin = log
    r = cli(["identify", "--robot", ctx["robot_file"], "--data", log, twin, "--out", w / "o", "--method", "ols",
             "--no-plot", "--joint-terms", "fv,fc"])
    bad, msg = cli_outcome(r, f"service/duplicates {how}")
    if bad:
        return bad, msg
    if r.exit_code == 0 and "given more than once" not in " ".join(r.output.split()):
        return "garbage", f"service/duplicates {how}: the same log was read twice without a warning"
    return "typed" if r.exit_code else "ok", ""

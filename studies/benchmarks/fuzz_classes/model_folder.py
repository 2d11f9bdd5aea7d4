"""Class ``model_folder``: tampered ``sensorless identify`` outputs fed to predict / estimate-force / payload / monitor.

Each worker identifies the two-link arm once (OLS, a 300-sample simulated log); each case copies
that folder and mutates result.json (types swapped, numbers → strings, lists, NaN, 1e150, −50;
keys deleted or added; absurd preprocessing settings; stored paths pointing at a planted secret;
truncated JSON; a FIFO, a directory or a symlink in its place), joint_terms.json or the gains,
then runs a command through CliRunner. ``garbage``: exit 0 with non-finite or absurd outputs
(|τ| or |F| > 1e6, a payload mass > 1e4 kg), or a physically impossible mutation (mass < 0 or
> 1e4 kg, gains of 1e6) accepted without a warning; ``generic``: exit 3, "internal error" or an
uncaught exception; ``disclosure``: the secret in the output text or files.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from .common import cli, cli_outcome, leaked, plant_secret, setup_model, warned

VALUES = [-50.0, 1e150, float("nan"), float("inf"), "abc", "", [1, 2], {"a": 1}, None, True, 0, -1, 1e9, 1e-12, "1e3"]
PREPROC = ["columns", "gains", "rate", "resample", "lowpass", "savgol_window", "velocity", "max_gap", "trim",
           "decimate", "rest", "time_unit"]


def setup(d: Path, scale: float) -> dict:
    ctx = setup_model(d)
    ctx["secret"], ctx["s"] = plant_secret(d)
    ctx["doc"] = json.loads((ctx["model"] / "result.json").read_text())
    return ctx


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _walk(doc, rng, depth=0):
    """A random (container, key) inside ``doc``."""
    keys = list(doc) if isinstance(doc, dict) else list(range(len(doc)))
    if not keys:
        return None
    k = _pick(rng, keys)
    v = doc[k]
    if isinstance(v, (dict, list)) and v and rng.random() < 0.6 and depth < 4:
        return _walk(v, rng, depth + 1) or (doc, k)
    return doc, k


def mutate(rng, m: Path, ctx: dict, ops: int = 10) -> tuple[str, bool]:
    """Mutate the model folder ``m``; (description, True when the mutation is physically absurd)."""
    doc = json.loads(json.dumps(ctx["doc"]))
    secret = str(ctx["secret"])
    op = int(rng.integers(ops))
    absurd = False
    if op == 0:  # a body mass
        key = _pick(rng, ["j1.m", "j2.m"])
        val = _pick(rng, [-50.0, 1e150, 1e5, -1e-6, float("nan"), "abc", [1.0], None])
        doc["parameters"][key] = val
        absurd = isinstance(val, float) and (val < 0 or val > 1e4)
        desc = f"parameters.{key}={val!r}"
    elif op == 1:  # any parameter
        key = _pick(rng, list(doc["parameters"]))
        val = _pick(rng, VALUES)
        doc["parameters"][key] = val
        desc = f"parameters.{key}={val!r}"
    elif op == 2:  # a preprocessing setting
        key = _pick(rng, PREPROC)
        val = _pick(rng, VALUES + [secret, "q=0:9", "bogus", "1e9:2e9", {"j1": 1e6, "j2": 1e6}, {"q": [0, 1]}])
        doc["settings"]["preprocessing"][key] = val
        absurd = val == {"j1": 1e6, "j2": 1e6}
        desc = f"settings.preprocessing.{key}={val!r}"[:120]
    elif op == 3:  # any value anywhere
        where = _walk(doc, rng)
        if where:
            where[0][where[1]] = _pick(rng, VALUES + [secret])
        desc = f"random value at {where[1] if where else '-'}"
    elif op == 4:  # delete a key
        where = _walk(doc, rng)
        if where:
            del where[0][where[1]]
        desc = f"deleted {where[1] if where else '-'}"
    elif op == 5:  # add keys / swap types of a section
        sec = _pick(rng, ["parameters", "joint_terms", "settings", "robot", "base_parameters"])
        doc[sec] = _pick(rng, [[], "x", 5, None, {"extra": 1}, dict(doc.get(sec) or {}, **{"zz.m": 3.0})])
        desc = f"{sec} swapped"
    elif op == 6:  # stored paths point outside
        doc["settings"]["data"] = [secret]
        doc["settings"]["preprocessing"]["gains"] = _pick(rng, [secret, f"../../../../..{secret}", "/etc/shadow"])
        doc["urdf"] = secret
        desc = "stored paths → secret"
    elif op == 7:  # joint_terms.json
        try:
            jt = json.loads((m / "joint_terms.json").read_text())
        except ValueError:  # truncated by the first of two edits
            return "joint_terms.json truncated", False
        j = _pick(rng, list(jt))
        jt[j][_pick(rng, list(jt[j]))] = _pick(rng, VALUES)
        (m / "joint_terms.json").write_text(json.dumps(jt) if rng.random() < 0.8 else json.dumps(jt)[:20])
        return f"joint_terms.json {j}", False
    elif op == 8:  # the file itself
        f = m / "result.json"
        kind = _pick(rng, ["truncated", "fifo", "dir", "symlink", "empty", "binary"])
        text = f.read_text()
        f.unlink()
        if kind == "truncated":
            f.write_text(text[: int(rng.integers(0, len(text)))])
        elif kind == "fifo":
            os.mkfifo(f)
        elif kind == "dir":
            f.mkdir()
        elif kind == "symlink":
            f.symlink_to(secret)
        elif kind == "empty":
            f.write_text("")
        else:
            f.write_bytes(bytes(rng.integers(0, 256, 300).tolist()))
        return f"result.json {kind}", False
    else:  # several at once
        # two edits of the document (not of the file itself: a replaced result.json cannot be edited)
        desc = "; ".join(mutate(rng, m, ctx, ops=8)[0] for _ in range(2))
        return desc, False
    (m / "result.json").write_text(json.dumps(doc, allow_nan=True))
    return desc, absurd


def _absurd_output(cmd: str, out: Path) -> str | None:
    try:
        if cmd == "payload":
            mass = json.loads(out.read_text()).get("mass")
            mass = float(mass["value"] if isinstance(mass, dict) else mass)
            return None if np.isfinite(mass) and abs(mass) < 1e4 else f"payload mass {mass}"
        if cmd == "monitor":
            return None if (out / "monitor.json").is_file() else "monitor: no monitor.json"
        with np.load(out, allow_pickle=False) as z:
            x = np.asarray(z["tau_pred" if cmd == "predict" else "force"], dtype=float)
        return None if np.all(np.isfinite(x)) and np.max(np.abs(x), initial=0) < 1e6 else f"{cmd}: max |x| {np.max(np.abs(x))}"
    except Exception as exc:  # noqa: BLE001 - an unreadable output of a successful run is garbage too
        return f"{cmd}: output unreadable ({type(exc).__name__})"


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    c = d / "case"
    c.mkdir()
    m = c / "model"
    shutil.copytree(ctx["model"], m)
    desc, absurd = mutate(rng, m, ctx)
    cmd = _pick(rng, ["predict"] * 6 + ["estimate-force", "payload", "monitor"])
    out = c / {"predict": "p.npz", "estimate-force": "f.npz", "payload": "pl.json", "monitor": "mon"}[cmd]
    args = [cmd, "--robot", ctx["robot_file"], "--model", m if rng.random() < 0.5 else m / "result.json",
            "--data", ctx["log"], "--out", out]
    if cmd in ("estimate-force", "payload"):
        args += ["--frame", "l2"]
    if cmd == "payload":
        args += ["--n-boot", "0"]
    r = cli(args)
    files = [out] if out.exists() else []
    if leaked(ctx["s"], r.output, files=files):
        return "disclosure", f"model_folder/{cmd} {desc}: the planted secret appears in the output"
    outcome, msg = cli_outcome(r, f"model_folder/{cmd} {desc}")
    if outcome:
        return outcome, msg
    bad = _absurd_output(cmd, out)
    if bad:
        return "garbage", f"model_folder/{cmd} {desc}: exit 0 with {bad}"
    if absurd and not warned(r.output):
        return "garbage", f"model_folder/{cmd} {desc}: accepted without a warning"
    return "ok", ""

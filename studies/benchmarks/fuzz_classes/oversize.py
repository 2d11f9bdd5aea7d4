"""Class ``oversize``: special files as path arguments, declared-size bombs, HDF5 indirection, huge CSV lines.

* a FIFO, /dev/zero, /dev/urandom, a private null device or a directory as every path argument
  (identify --data/--gains/--config/--weights/--prior/--validate, predict --model/--data/--gains,
  monitor --model) through the CLI;
* NPZ members whose hand-written ``.npy`` header declares 10⁹–10¹² elements, with a short payload
  or a deflated stream of zeros (built once per worker, streamed: nothing that size is allocated);
* HDF5 with huge declared chunked shapes, external raw storage and virtual datasets pointing at a
  planted file of sentinel values (``disclosure`` when the sentinel comes back), or at a missing
  source (``garbage`` when it silently reads as fill values);
* a CSV of one very long line (40 MB × scale, at least 1 MB) and a header of 150,000 fields.
"""

from __future__ import annotations

import os
import struct
import zipfile
from pathlib import Path

import numpy as np

from .common import cli, cli_outcome, make_device, one_line, setup_model

SENTINEL = 0.4242424242


def _npy_header(shape: tuple, descr: str = "<f8") -> bytes:
    d = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}"
    pad = 64 - (10 + len(d) + 1) % 64
    d = d + " " * pad + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(d)) + d.encode()


def _bomb_member(zf: zipfile.ZipFile, name: str, shape: tuple, zeros: int) -> None:
    with zf.open(name, "w", force_zip64=True) as fh:
        fh.write(_npy_header(shape))
        chunk = bytes(1 << 20)
        left = zeros
        while left > 0:
            fh.write(chunk[: min(left, len(chunk))])
            left -= len(chunk)


def setup(d: Path, scale: float) -> dict:
    ctx = setup_model(d)
    zeros = int(min(1.0, max(scale, 0.02)) * 2e9)  # decompressed size of the zip bomb
    bomb = d / "bomb.npz"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as zf:
        _bomb_member(zf, "positions.npy", (10 ** 9, 2), zeros)
        _bomb_member(zf, "times.npy", (10 ** 9,), 0)
    ctx["bomb"] = bomb
    sentinel = SENTINEL + 1e-9 * np.arange(400).reshape(200, 2)
    ctx["secret_bin"] = d / "secret.bin"
    ctx["secret_bin"].write_bytes(sentinel.tobytes())
    import h5py

    ctx["secret_h5"] = d / "secret.h5"
    with h5py.File(ctx["secret_h5"], "w") as h:
        h["data"] = sentinel
    fifo = d / "fifo"
    os.mkfifo(fifo)
    (d / "adir").mkdir()
    ctx["specials"] = [fifo, Path("/dev/zero"), Path("/dev/urandom"), d / "adir"]
    if make_device(d / "null"):
        ctx["specials"].append(d / "null")
    ctx["line_bytes"] = int(40e6 * min(1.0, max(scale, 0.025)))
    return ctx


def special_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    sp = ctx["specials"][int(rng.integers(len(ctx["specials"])))]
    robot, log, model, out = ctx["robot_file"], ctx["log"], ctx["model"], d / "case" / "o"
    arg = str(rng.choice(["id:--data", "id:--gains", "id:--config", "id:--weights", "id:--prior", "id:--validate",
                          "pr:--model", "pr:--data", "pr:--gains", "mo:--model"]))
    cmd, flag = arg.split(":")
    if cmd == "id":
        args = {"--data": sp, "--robot": robot, "--out": out, "--method": "lmi" if flag == "--prior" else "ols",
                "--no-plot": None}
        args[flag] = sp
    elif cmd == "pr":
        args = {"--robot": robot, "--model": model, "--data": log, "--out": d / "case" / "p.npz"}
        args[flag] = sp
    else:
        args = {"--robot": robot, "--model": sp, "--data": log, "--out": out}
    if cmd == "id" and flag != "--data":
        args["--data"] = log
    argv = [{"id": "identify", "pr": "predict", "mo": "monitor"}[cmd]]
    for k, v in args.items():
        argv += [k] if v is None else [k, v]
    r = cli(argv)
    outcome, msg = cli_outcome(r, f"oversize/{argv[0]} {flag} {sp.name}")
    if outcome is None:  # exit 0 with a special file as an input
        return "garbage", f"oversize/{argv[0]} {flag} {sp}: accepted (exit 0)"
    return outcome, msg


def _h5(rng, f: Path, ctx: dict) -> str:
    import h5py

    kind = str(rng.choice(["huge", "external", "vds", "vds_missing"]))
    n = 200
    with h5py.File(f, "w") as h:
        h["times"] = np.arange(n) / 100.0
        h["torques"] = np.ones((n, 2))
        if kind == "huge":
            big = int(10 ** rng.uniform(9, 12))
            h.create_dataset("positions", shape=(big, 2), dtype="f8", chunks=(4096, 2), fillvalue=0.1)
            if rng.random() < 0.5:
                del h["times"]
                h.create_dataset("times", shape=(big,), dtype="f8", chunks=(4096,), fillvalue=0.0)
        elif kind == "external":
            h.create_dataset("positions", shape=(n, 2), dtype="f8", external=[(str(ctx["secret_bin"]), 0, n * 16)])
        else:
            src = ctx["secret_h5"] if kind == "vds" else f.parent / "missing.h5"
            layout = h5py.VirtualLayout(shape=(n, 2), dtype="f8")
            layout[:] = h5py.VirtualSource(str(src), "data", shape=(n, 2))
            h.create_virtual_dataset("positions", layout, fillvalue=0.0)
    return kind


def file_case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.data import read_trajectory
    from sensorless.errors import SensorlessError

    case = d / "case"
    kind = str(rng.choice(["npz_bomb", "npz_header", "hdf5", "csv_line", "csv_fields"], p=[.2, .25, .35, .1, .1]))
    kw: dict = {"rate": 100.0}
    if kind == "npz_bomb":
        f = ctx["bomb"]
    elif kind == "npz_header":
        f = case / "h.npz"
        with zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED if rng.random() < 0.5 else zipfile.ZIP_STORED) as zf:
            n = int(10 ** rng.uniform(9, 12))
            for name, shape in (("times", (n,)), ("positions", (n, 2)), ("torques", (n, 2))):
                with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    fh.write(_npy_header(shape) + bytes(int(rng.integers(0, 4096))))
    elif kind == "hdf5":
        f = case / "f.h5"
        kind = "hdf5_" + _h5(rng, f, ctx)
    elif kind == "csv_line":
        f = case / "line.csv"
        reps = ctx["line_bytes"] // 4
        f.write_bytes(b"t,q_a\n" + b"1.0," * reps if rng.random() < 0.5 else b"1.0," * reps)
        kw = {"columns": {"q": "0:2"}, "rate": 100.0} if rng.random() < 0.5 else kw
    else:
        f = case / "fields.csv"
        names = ["t"] + [f"q_{i}" for i in range(150_000)]
        f.write_text(",".join(names) + "\n" + "\n".join(",".join(["0.1"] * len(names)) for _ in range(2)))
    try:
        tr = read_trajectory(f, **kw)
    except SensorlessError:
        return "typed", ""
    except Exception as exc:  # noqa: BLE001
        return "generic", f"oversize/{kind}: {type(exc).__name__}: {one_line(exc)}"
    arrays = [a for a in (tr.t, tr.q, tr.v, tr.a, tr.tau) if a is not None]
    if any(np.any(np.abs(np.asarray(a, float) - SENTINEL) < 1e-3) for a in arrays):
        return "disclosure", f"oversize/{kind}: another file's contents were read into the log"
    if kind == "hdf5_vds_missing":
        return "garbage", "oversize/hdf5_vds_missing: a missing virtual-dataset source read as fill values"
    return "ok", ""


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    (d / "case").mkdir(exist_ok=True)
    return special_case(rng, d, ctx) if rng.random() < 0.35 else file_case(rng, d, ctx)

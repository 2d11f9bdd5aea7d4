"""Class ``formats`` (issue 27's log formats): MATLAB v7.3 and v5 ``.mat`` files, per-signal text
folders and single whitespace ``.dat`` files, and ``--skip-bad-rows`` / ``--trim FILE=WINDOW``.

Every case starts from the worker's simulated two-link log (300 samples at 100 Hz) written in one
of the formats, then damages it:

* ``mat73`` (tests/matlab_writer.py layout): a wrong or missing ``MATLAB_class``, odd char arrays
  (empty, 3-D, lone surrogates, code points past U+10FFFF), cell references to deleted datasets,
  groups or numbers, string objects, N × N arrays, channel-major arrays of mismatched lengths,
  ``MATLAB_empty`` on data, a truncated or bit-flipped file;
* ``mat5`` (``scipy.io.savemat``): text, cells, structs, complex, integer, logical, 3-D or empty
  variables in place of the log's;
* ``folder`` / ``dat``: tick columns with and without ``--time-unit tick --rate``, non-integer or
  backward ticks, files sharing few stamps, a missing file, mixed delimiters, NaN/inf, very long lines;
* ``cli``: ``sensorless predict`` on a ``.dat`` log with a corrupt prefix, suffix or middle, with
  ``--skip-bad-rows`` and ``--trim [FILE=]WINDOW`` combinations.

``garbage``: success (or exit 0) where a returned sample's time is not one written, its positions
or torques differ from those written at that time, or fewer samples than written came back with
no warning (a trim asked for counts as said).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from .common import cli, cli_outcome, one_line, setup_model, warned

TESTS = Path(__file__).resolve().parents[3] / "tests"
RATE = 1000.0  # tick rate: the 100 Hz log logs every 10th tick
TICK0 = 1000


def setup(d: Path, scale: float) -> dict:
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    ctx = setup_model(d)
    tr = ctx["traj"]
    ctx["ticks"] = TICK0 + 10 * np.arange(len(tr.t))
    ctx["names"] = tuple(tr.joint_names)
    return ctx


# ---- checking what came back ---------------------------------------------------------------------
def compare(t, q, tau, wt, wq, wtau, caught: bool, what: str, expect_fewer: bool = False):
    """(outcome, message) of a successful read: every sample one written (time, q, tau)."""
    if not (np.all(np.isfinite(q)) and (tau is None or np.all(np.isfinite(tau)))):
        return "garbage", f"{what}: non-finite values returned"
    idx = np.searchsorted(wt, t)
    idx = np.clip(idx, 0, len(wt) - 1)
    near = np.abs(wt[idx] - t) <= 1e-9 * np.maximum(1.0, np.abs(t))
    alt = np.clip(idx - 1, 0, len(wt) - 1)
    near_alt = np.abs(wt[alt] - t) <= 1e-9 * np.maximum(1.0, np.abs(t))
    idx = np.where(near, idx, alt)
    if not np.all(near | near_alt):
        k = int(np.flatnonzero(~(near | near_alt))[0])
        return "garbage", f"{what}: sample {k} at t={t[k]:.10g} was not written, no error"
    if q.shape != wq[idx].shape or not np.allclose(q, wq[idx], rtol=1e-9, atol=1e-12):
        return "garbage", f"{what}: positions differ from those written (shape {q.shape} vs {wq[idx].shape}), no error"
    if tau is not None and wtau is not None and (tau.shape != wtau[idx].shape
                                                 or not np.allclose(tau, wtau[idx], rtol=1e-9, atol=1e-12)):
        return "garbage", f"{what}: torques differ from those written, no error"
    if len(t) < len(wt) and not caught and not expect_fewer:
        return "garbage", f"{what}: {len(t)} of {len(wt)} samples read, no warning"
    return "ok", ""


def read(path, what: str, wt, wq, wtau, **kw):
    from sensorless.data import read_trajectory
    from sensorless.errors import SensorlessError

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            tr = read_trajectory(path, **kw)
    except SensorlessError:
        return "typed", ""
    except RecursionError as exc:
        return "generic", f"{what}: RecursionError: {one_line(exc)}"
    except Exception as exc:  # noqa: BLE001 - what we count
        import traceback

        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return "generic", f"{what}: {type(exc).__name__}: {one_line(exc)} @ {Path(tb.filename).name}:{tb.lineno}"
    return compare(tr.t, tr.q, tr.tau, wt, wq, wtau, bool(caught), what)


# ---- MATLAB v7.3 -------------------------------------------------------------------------------------
MAT73_KINDS = ("class", "char_odd", "cell_ref", "string", "square", "channel_major", "empty", "truncate", "flip",
               "clean")


def mat73_case(rng, d: Path, ctx: dict):
    import h5py
    from matlab_writer import CellStr, MatlabString, write_mat73

    tr = ctx["traj"]
    t, q, tau = tr.t.copy(), tr.q.copy(), tr.tau.copy()
    kind = str(rng.choice(MAT73_KINDS))
    what = f"formats/mat73 {kind}"
    names = [CellStr(ctx["names"]), list(ctx["names"]), MatlabString(ctx["names"])][int(rng.integers(3))]
    qv, tv, tauv = q, t, tau
    if kind == "square":
        m = int(rng.choice([2, len(t)]))
        qv, tv, tauv = (rng.normal(size=(m, m)), t[:m], tau[:m]) if m == 2 else (rng.normal(size=(m, m)), t, tau)
        what += f" {m}x{m}"
        q = qv
    elif kind == "channel_major":
        k = int(rng.integers(0, 4))
        qv, tauv = q.T, tau[: len(t) - k].T
        if rng.random() < 0.5:
            tv = t[: len(t) - int(rng.integers(0, 3))]
        what += f" tau short by {k}"
    variables = {"t": tv, "q": qv, "tau": tauv, "joint_names": names}
    if rng.random() < 0.3:
        variables = {"data": variables}
    f = d / "case" / ("log.mat" if rng.random() < 0.8 else "log.h5")
    write_mat73(f, variables)
    pre = "data/" if "data" in variables else ""
    with h5py.File(f, "r+") as h:
        if kind == "class":
            key = pre + str(rng.choice(["t", "q", "tau", "joint_names"]))
            if rng.random() < 0.2:
                del h[key].attrs["MATLAB_class"]
            else:
                h[key].attrs["MATLAB_class"] = np.bytes_(str(rng.choice(
                    ["char", "cell", "struct", "string", "int8", "logical", "bogus", "", "function_handle"])))
            what += f" {key}"
        elif kind == "char_odd":
            del h[pre + "joint_names"]
            shape = [(0,), (2,), (3, 4, 2), (1, 1), (4, 2)][int(rng.integers(5))]
            dtype = str(rng.choice(["u2", "u4", "f8", "i8"]))
            vals = rng.choice([0, 32, 0xD800, 0xDFFF, 0xFFFF, 0x110000, 2 ** 31 - 1, 106, 49], size=shape)
            with np.errstate(all="ignore"):
                ds = h.create_dataset(pre + "joint_names", data=np.asarray(vals).astype(dtype))
            ds.attrs["MATLAB_class"] = np.bytes_("char")
            ds.attrs["MATLAB_int_decode"] = np.int32(2)
            what += f" {shape} {dtype}"
        elif kind == "cell_ref":
            del h[pre + "joint_names"]
            target = str(rng.choice(["deleted", "null", "group", "number", "self", "struct"]))
            if target == "deleted":
                tmp = h["#refs#"].create_dataset("zz", data=np.zeros(2))
                ref = tmp.ref
                del h["#refs#/zz"]
            elif target == "null":
                ref = h5py.Reference()
            elif target == "group":
                ref = h["#refs#"].ref
            elif target in ("number", "struct"):
                tmp = h["#refs#"].create_dataset("zz", data=np.ones((2, 1)))
                tmp.attrs["MATLAB_class"] = np.bytes_("double" if target == "number" else "struct")
                ref = tmp.ref
            else:
                ref = None
            ds = h.create_dataset(pre + "joint_names", shape=(2, 1), dtype=h5py.ref_dtype)
            ds.attrs["MATLAB_class"] = np.bytes_("cell")
            ds[0, 0] = ds.ref if ref is None else ref
            ds[1, 0] = ds.ref if ref is None else ref
            what += f" {target}"
        elif kind == "string":
            key = pre + str(rng.choice(["q", "tau", "t"]))
            h[key].attrs["MATLAB_class"] = np.bytes_("string")
            h[key].attrs["MATLAB_object_decode"] = np.int32(3)
            what += f" {key}"
        elif kind == "empty":
            key = pre + str(rng.choice(["q", "tau", "t", "joint_names"]))
            h[key].attrs["MATLAB_empty"] = np.uint8(1)
            what += f" {key}"
    if kind in ("truncate", "flip"):
        data = bytearray(f.read_bytes())
        if kind == "truncate":
            data = data[: int(rng.integers(0, len(data)))]
        else:  # flips in the file's structure: flipped raw numbers are undetectable without a checksum
            raw = np.zeros(len(data), bool)
            with h5py.File(f, "r") as h:
                h.visititems(lambda name, obj: _mark_raw(obj, raw))
            spots = np.flatnonzero(~raw)
            for k in rng.choice(spots, size=int(rng.integers(1, 30))):
                data[int(k)] = int(rng.integers(0, 256))
        f.write_bytes(bytes(data))
    return read(f, what, t, q, tau)


def _mark_raw(obj, raw: np.ndarray) -> None:
    import h5py

    if isinstance(obj, h5py.Dataset) and obj.id.get_offset() is not None:
        off = obj.id.get_offset()
        raw[off:off + obj.id.get_storage_size()] = True


# ---- MATLAB v5 -----------------------------------------------------------------------------------
def mat5_case(rng, d: Path, ctx: dict):
    import scipy.io

    tr = ctx["traj"]
    t, q, tau = tr.t.copy(), tr.q.copy(), tr.tau.copy()
    odd = str(rng.choice(["names_obj", "names_num", "q_int", "q_complex", "q_bool", "q_text", "q_cell", "q_3d",
                          "q_empty", "t_text", "struct", "struct_array", "nested", "q_row", "clean"]))
    names = np.array(ctx["names"], dtype=object) if rng.random() < 0.5 else np.array(ctx["names"])
    v = {"t": t, "q": q, "tau": tau, "joint_names": names}
    if odd == "names_obj":
        v["joint_names"] = np.array([1.5, "x", np.zeros(2), {"a": 1.0}], dtype=object)[: int(rng.integers(1, 5))]
    elif odd == "names_num":
        v["joint_names"] = np.array([1.0, 2.0])
    elif odd == "q_int":
        q = np.round(q * 1000).astype(np.int16)
        v["q"] = q
    elif odd == "q_complex":
        v["q"] = q + 1j
    elif odd == "q_bool":
        q = (q > 0)
        v["q"] = q
        q = q.astype(float)
    elif odd == "q_text":
        v["q"] = "not numbers"
    elif odd == "q_cell":
        v["q"] = np.array([q[:, 0], q[:, 1]], dtype=object) if rng.random() < 0.5 else np.array([q, "x"], dtype=object)
    elif odd == "q_3d":
        v["q"] = np.stack([q, q], axis=2)
    elif odd == "q_empty":
        v["q"] = np.zeros((0, 2))
    elif odd == "t_text":
        v["t"] = np.array([str(x) for x in t])
    elif odd == "struct":
        v = {"log": v}
    elif odd == "struct_array":
        v = {"log": np.array([(t, q), (t, q)], dtype=[("t", object), ("q", object)])}
    elif odd == "nested":
        v = {"a": {"b": {"c": v}}}
    elif odd == "q_row":
        v["q"] = q.T
    f = d / "case" / "log.mat"
    try:
        scipy.io.savemat(str(f), v, do_compression=bool(rng.random() < 0.5),
                         format="4" if rng.random() < 0.1 else "5")
    except Exception:  # noqa: BLE001 - v4 holds no text, cells or structs
        scipy.io.savemat(str(f), v)
    if rng.random() < 0.15:
        data = bytearray(f.read_bytes())
        data = data[: int(rng.integers(0, len(data)))]
        f.write_bytes(bytes(data))
        odd += " truncated"
    return read(f, f"formats/mat5 {odd}", t, np.asarray(q, dtype=float), tau)


# ---- text: folder of per-signal files, one .dat file -------------------------------------------------
TEXT_KINDS = ("clean", "no_unit", "fractional", "backwards", "few_shared", "some_shared", "missing", "delims", "nan",
              "long_line", "long_number", "seconds")


def _rows(ticks, vals, fmt_tick="%d") -> list[str]:
    tick = (lambda x: repr(float(x))) if fmt_tick == "%r" else (lambda x: fmt_tick % x)
    return [" ".join([tick(tk), *(repr(float(x)) for x in r)]) for tk, r in zip(ticks, vals)]


def _damage_lines(rng, lines: list[str], kind: str, n_header: int, vals: np.ndarray) -> tuple[list[str], str]:
    """``lines`` damaged by ``kind``; ``vals`` (the values written, rows × columns after the time)
    takes a long number's value."""
    body = list(range(n_header, len(lines)))
    k = int(rng.choice(body))
    if kind == "delims":
        sep = str(rng.choice([",", "\t", ";", " , ", "\t\t"]))
        for j in rng.choice(body, size=int(rng.integers(1, 5)), replace=False):
            lines[int(j)] = sep.join(lines[int(j)].split())
    elif kind == "nan":
        parts = lines[k].split()
        parts[int(rng.integers(len(parts)))] = str(rng.choice(["nan", "inf", "-inf", "NaN", "1e400"]))
        lines[k] = " ".join(parts)
    elif kind == "long_line":
        lines[k] = lines[k] + " " + " ".join(["1.0"] * int(rng.choice([10, 1000, 100_000])))
    elif kind == "long_number":
        parts = lines[k].split()
        parts[-1] = "1." + "3" * int(rng.choice([400, 100_000, 2_000_000]))
        lines[k] = " ".join(parts)
        vals[k - n_header, -1] = 4.0 / 3.0
    return lines, f"row {k}"


def text_case(rng, d: Path, ctx: dict, folder: bool):
    tr = ctx["traj"]
    t, q, tau = tr.t.copy(), tr.q.copy(), tr.tau.copy()
    ticks = ctx["ticks"].astype(float)
    kind = str(rng.choice(TEXT_KINDS))
    what = f"formats/{'folder' if folder else 'dat'} {kind}"
    header = rng.random() < 0.7
    names = ctx["names"]
    kw = {"time_unit": "tick", "rate": RATE}
    tick_fmt = "%d"
    if kind == "no_unit":
        kw = {} if rng.random() < 0.5 else {"rate": RATE}
    elif kind == "seconds":
        ticks, kw, tick_fmt = t.copy(), {}, "%r"
    elif kind == "fractional":
        ticks = ticks + np.round(rng.uniform(-0.4, 0.4, size=len(ticks)), 3) * (rng.random() < 0.5)
        if rng.random() < 0.5:
            ticks[int(rng.integers(len(ticks)))] += 0.5
        tick_fmt = "%r"
    elif kind == "backwards":
        k = int(rng.integers(1, len(ticks)))
        ticks[k] = ticks[k - 1] - float(rng.choice([1, 10, 1000]))
    wt = ticks / RATE if kw.get("time_unit") == "tick" else ticks
    tcol = str(rng.choice(["tick", "t", "time", "counter"]))
    d_case = d / "case"
    if folder:
        tau_ticks = ticks.copy()
        if kind == "few_shared":
            tau_ticks = ticks + 5  # no stamp in common
        elif kind == "some_shared":
            tau_ticks = ticks.copy()
            m = int(rng.integers(1, len(ticks) // 2))
            tau_ticks[-m:] += 5
        run = d_case / "run"
        run.mkdir()
        q, tau = q.copy(), tau.copy()
        files = {"q": (ticks, q), "tau": (tau_ticks, tau)}
        if rng.random() < 0.3:
            files["dq"] = (ticks, tr.v)
        for stem, (tk, vals) in files.items():
            lines = ([" ".join([tcol, *names])] if header else []) + _rows(tk, vals, tick_fmt)
            if kind in ("delims", "nan", "long_line", "long_number") and (stem == "q" or rng.random() < 0.3):
                lines, where = _damage_lines(rng, lines, kind, int(header), vals)
                what += f" {stem}.dat {where}"
            (run / f"{stem}.{rng.choice(['dat', 'txt'])}").write_text("\n".join(lines) + "\n")
        if kind == "missing":
            stem = str(rng.choice(list(files)))
            victim = next(p for p in run.iterdir() if p.stem == stem)
            victim.unlink()
            what += f" {victim.name}"
        if kind == "some_shared":
            common = np.intersect1d(ticks, tau_ticks)
            keep = np.isin(ticks, common)
            wt, q, tau = wt[keep], q[keep], tau[np.isin(tau_ticks, common)]
        path = run
    else:
        cols = [tcol, *(f"q_{n}" for n in names), *(f"tau_{n}" for n in names)]
        vals = np.column_stack([q, tau])
        lines = ([" ".join(cols)] if header else []) + _rows(ticks, vals, tick_fmt)
        if kind in ("delims", "nan", "long_line", "long_number"):
            lines, where = _damage_lines(rng, lines, kind, int(header), vals)
            what += f" {where}"
            q, tau = vals[:, :2], vals[:, 2:]
        if kind == "missing":
            lines = lines[: int(header)]
        path = d_case / f"run.{rng.choice(['dat', 'txt'])}"
        path.write_text("\n".join(lines) + "\n")
        if not header:
            kw["columns"] = {"t": "0", "q": "1:3", "tau": "3:5"}
            if rng.random() < 0.2:  # no time column named: the stamps are the row count over --rate
                kw["columns"] = {"q": "1:3", "tau": "3:5"}
                kw.pop("time_unit", None)
                wt = np.arange(len(wt)) / kw.setdefault("rate", RATE)
    if kind == "few_shared" and not folder:
        return "ok", ""
    order = np.argsort(wt, kind="stable")
    return read(path, what, wt[order], q[order], tau[order], **kw)


# ---- the CLI: --skip-bad-rows, --trim [FILE=]WINDOW ----------------------------------------------------
def cli_case(rng, d: Path, ctx: dict):
    tr = ctx["traj"]
    t, q, tau = tr.t.copy(), tr.q.copy(), tr.tau.copy()
    n = len(t)
    where = str(rng.choice(["prefix", "suffix", "middle", "both", "none"]))
    span = int(rng.choice([1, 3, 10, 20, 40]))
    bad = np.zeros(n, bool)
    if where in ("prefix", "both"):
        bad[:span] = True
    if where in ("suffix", "both"):
        bad[n - span:] = True
    if where == "middle":
        a = int(rng.integers(span + 1, n - span - 1))
        bad[a:a + span] = True
    rows = np.column_stack([10 * np.arange(n) + TICK0, q, tr.v, tau]).astype(object)
    how = str(rng.choice(["nan", "absurd", "backwards", "text"]))
    for k in np.flatnonzero(bad):
        c = int(rng.integers(1, 7))
        if how == "nan":
            rows[k, c] = "nan"
        elif how == "absurd":
            rows[k, c] = 1e30
        elif how == "backwards":  # a prefix later than the log, a middle or suffix back at zero
            rows[k, 0] = TICK0 + 10 * (n + k) if where in ("prefix", "both") and k < n // 2 else 0
        else:
            rows[k, c] = "#?"
    names = ctx["names"]
    header = " ".join(["tick", *(f"q_{x}" for x in names), *(f"dq_{x}" for x in names), *(f"tau_{x}" for x in names)])
    lines = [header] + [" ".join(str(int(r[0])) if isinstance(r[0], (int, np.integer, float)) and j == 0 else
                                 (repr(float(x)) if isinstance(x, (float, np.floating)) else str(x))
                                 for j, x in enumerate(r)) for r in rows]
    if where in ("suffix", "both") and rng.random() < 0.5:
        lines[-1] = lines[-1][: int(rng.integers(1, len(lines[-1])))]  # the last row cut short
    name = f"run.{rng.choice(['dat', 'txt'])}"
    f = d / "case" / name
    f.write_text("\n".join(lines) + "\n")
    args = ["predict", "--robot", ctx["robot_file"], "--model", ctx["model"], "--data", f, "--out",
            d / "case" / "p.npz", "--time-unit", "tick", "--rate", RATE]
    skip = rng.random() < 0.6
    if skip:
        args.append("--skip-bad-rows")
    trimmed = False
    tsec = t.copy()
    lo, hi = tsec[0] + span * 0.01 + 0.1, tsec[-1] - span * 0.01 - 0.1
    if rng.random() < 0.5:
        win = str(rng.choice([f"abs:{TICK0 / RATE + lo:.4f}:{TICK0 / RATE + hi:.4f}", f"{lo:.3f}:", f":{-(0.1 + span * 0.01):.3f}",
                              "0.5:1.5", "5:9", "abs:0:1", "x:y", "1:0"]))
        args += ["--trim", f"{rng.choice([name, str(f), 'other.dat', ''])}={win}" if rng.random() < 0.7 else win]
        args[-1] = args[-1].lstrip("=")
        trimmed = True
    what = f"formats/cli {where} {how} x{span} skip={skip} {' '.join(map(str, args[11:]))}"
    r = cli(args)
    outcome, msg = cli_outcome(r, what)
    if outcome:
        return outcome, msg
    with np.load(d / "case" / "p.npz") as z:
        ot = z["t"]
        meas = z["tau_measured"] if "tau_measured" in z.files else None
        pred = z["tau_pred"]
    if not np.all(np.isfinite(pred)):
        return "garbage", f"{what}: non-finite predicted torques, exit 0"
    wt = TICK0 / RATE + t
    keep = ~bad
    res = compare(ot, np.zeros((len(ot), 0)), meas, wt[keep], np.zeros((int(keep.sum()), 0)), tau[keep],
                  warned(r.output), what, expect_fewer=trimmed)
    return res


def case(rng, d: Path, ctx: dict):
    (d / "case").mkdir(exist_ok=True)
    u = rng.random()
    if u < 0.3:
        return mat73_case(rng, d, ctx)
    if u < 0.45:
        return mat5_case(rng, d, ctx)
    if u < 0.65:
        return text_case(rng, d, ctx, folder=True)
    if u < 0.8:
        return text_case(rng, d, ctx, folder=False)
    return cli_case(rng, d, ctx)

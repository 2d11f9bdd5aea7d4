"""Errors in the user's language (issue 24): a table of bad command lines across the commands,
each answered by exit code 2 and one line in the flags of the command that ran: no Python
(`=[`, `pass x=`, keyword-argument advice, unrendered `field` settings), no advice to drop a
flag the user never gave, no flag the command does not have. Plus the mechanism itself
(errors.setting → cli.flags.cli_words), the static scan of the package's messages, and
--angle-unit deg (recorded, reused by predict)."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import typer
from typer.main import get_command
from typer.testing import CliRunner

from sensorless.cli import app
from sensorless.data import write_npz
from sensorless.errors import JointNameError, SensorlessError, python_only, setting, settings_in
from sensorless.excitation import random_fourier
from sensorless.testing import perturbed_truth, synthetic_trajectory

runner = CliRunner()
LOCK = ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2"]
PANDA = ["--robot", "panda", *LOCK]
SRC = Path(__file__).resolve().parents[1] / "src" / "sensorless"


def _run(args):
    return runner.invoke(app, [str(a) for a in args])


def _csv(tr, path, mutate=None, header=True, time=True, fields=("q", "v", "a", "tau")):
    cols = {"t": tr.t} if time else {}
    for f in fields:
        for j, name in enumerate(tr.joint_names):
            cols[f"{f}_{name}"] = getattr(tr, f)[:, j]
    df = pd.DataFrame(cols)
    df = mutate(df) if mutate else df
    df.to_csv(path, index=False, header=header)
    return path


def _set(df, col, row, value):
    df = df.copy()
    df[col] = df[col].astype(float)
    df.loc[row, col] = value
    return df


@pytest.fixture(scope="module")
def logs(tmp_path_factory, panda):
    """Tiny simulated Panda logs (400 samples), broken one way each, and an identified model."""
    d = tmp_path_factory.mktemp("error_language")
    truth = perturbed_truth(panda, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(panda, rng=1).sample(100, 4.0), noise_std=0.1, rng=2)
    write_npz(tr, d / "good.npz")
    _csv(tr, d / "good.csv")
    _csv(tr, d / "nan.csv", lambda df: _set(df, "tau_panda_joint3", 42, np.nan))
    _csv(tr, d / "nanstart.csv", lambda df: _set(df, "q_panda_joint2", 0, np.nan))
    _csv(tr, d / "deg.csv", lambda df: df.assign(**{c: np.degrees(df[c]) for c in df if c[:2] in ("q_", "v_", "a_")}))
    _csv(tr, d / "renamed.csv", lambda df: df.rename(columns=lambda c: c.replace("joint3", "jiont3")))
    _csv(tr, d / "notau.csv", fields=("q", "v", "a"))
    _csv(tr, d / "nohdr.csv", header=False, time=False, fields=("q", "v", "tau"))
    _csv(tr, d / "dup.csv", lambda df: _set(df, "t", 10, df.loc[9, "t"]))
    _csv(tr, d / "ms.csv", lambda df: df.assign(t=np.round(df["t"] * 1000).astype(int)))
    r = _run(["identify", *PANDA, "--data", d / "good.npz", "--method", "ols", "--joint-terms", "fv,fc,offset",
              "--no-plot", "--out", d / "model"])
    assert r.exit_code == 0, r.output
    (d / "empty_model").mkdir()
    (d / "corrupt_model").mkdir()
    (d / "corrupt_model" / "result.json").write_text("{not json")
    return d, tr


# (command line with D/ for the log folder, what the line must say)
CASES = [
    # identify: the quickstart-6 mistake, robots, joints, frames
    (["identify", "--robot", "panda", "--data", "D/good.npz"], ["good.npz", "--lock panda_finger_joint1 --lock panda_finger_joint2"]),
    (["identify", "--robot", "pandaa", *LOCK, "--data", "D/good.npz"], ["did you mean 'panda'?"]),
    (["identify", "--robot", "panda", "--lock", "panda_finger_joint", "--data", "D/good.npz"], ["did you mean 'panda_finger_joint"]),
    (["identify", *PANDA, "--passive", "panda_jiont7", "--data", "D/good.npz"], ["panda_jiont7", "did you mean 'panda_joint7'"]),
    (["identify", *PANDA, "--data", "D/renamed.csv"], ["renamed.csv", "did you mean 'panda_joint3'?", "--columns 'q=COL|COL|...'"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--contact-frames", "panda_hnd"], ["did you mean 'panda_hand'"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--add-frame", "tip:panda_lnk8:0,0,0.1"], ["did you mean 'panda_link8'"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--joint-terms", "panda_joint9=fv;*=fv,fc"], ["panda_joint9", "did you mean 'panda_joint"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--joint-terms", "fv,xx"], ["--joint-terms", "'xx'"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--wrench-frame", "panda_link8"], ["--wrench-frame needs --contact-mode wrench"]),
    # identify: bad logs
    (["identify", *PANDA, "--data", "D/nan.csv"], ["nan.csv", "panda_joint3", "42"]),
    (["identify", *PANDA, "--data", "D/nanstart.csv"], ["nanstart.csv", "--skip-bad-rows", "--trim nanstart.csv=abs:"]),
    (["identify", *PANDA, "--data", "D/deg.csv"], ["deg.csv", "look like degrees", "--angle-unit deg"]),
    (["identify", *PANDA, "--data", "D/notau.csv"], ["notau.csv", "tau"]),
    (["identify", *PANDA, "--data", "D/dup.csv", "--resample", "off"], ["dup.csv", "duplicate timestamp", "--resample auto"]),
    (["identify", *PANDA, "--data", "D/ms.csv"], ["ms.csv", "--time-unit ms", "--time-unit tick --rate HZ"]),
    (["identify", *PANDA, "--data", "D/missing.npz"], ["missing.npz", "no such file"]),
    (["identify", *PANDA, "--data", "D/nothing/**/*.parquet"], ["matches no file"]),
    # identify: columns, rate, time unit
    (["identify", *PANDA, "--data", "D/nohdr.csv"], ["no header row", "--columns 'q=0:7;v=7:14;tau=14:21'", "--rate HZ"]),
    (["identify", *PANDA, "--data", "D/nohdr.csv", "--columns", "q=0:7;v=7:14;tau=14:21"], ["no time column", "--rate HZ"]),
    (["identify", *PANDA, "--data", "D/nohdr.csv", "--columns", "q=0:7;v=7:14;tau=14:21", "--rate", "0"], ["--rate must be"]),
    (["identify", *PANDA, "--data", "D/good.csv", "--columns", "q0:7"], ["--columns", "'q0:7'"]),
    (["identify", *PANDA, "--data", "D/good.csv", "--columns", "q=pos_{joint}"], ["no column matches 'pos_{joint}'", "--columns 'q="]),
    (["identify", *PANDA, "--data", "D/good.csv", "--columns", "q=q_{joint};tau=trq_{joint}"], ["trq_panda_joint1", "did you mean", "'tau_panda_joint1' or"]),
    (["identify", *PANDA, "--data", "D/good.csv", "--time-unit", "tick"], ["--time-unit tick needs the tick rate: --rate HZ"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--workers", "2"], ["--workers needs --scheduler"]),
    (["identify", *PANDA, "--data", "D/good.npz", "--angle-unit", "grad"], ["--angle-unit", "'grad'"]),
    # predict: bad model folders, bad logs
    (["predict", "--robot", "panda", "--model", "D/nomodel", "--data", "D/good.npz"], ["nomodel", "no such model file"]),
    (["predict", "--robot", "panda", "--model", "D/empty_model", "--data", "D/good.npz"], ["empty_model", "result.json"]),
    (["predict", "--robot", "panda", "--model", "D/corrupt_model", "--data", "D/good.npz"], ["corrupt_model", "not valid JSON"]),
    (["predict", "--robot", "panda", "--model", "D/model", "--data", "D/deg.csv"], ["deg.csv", "--angle-unit deg"]),
    (["predict", "--robot", "panda", "--model", "D/model", "--data", "D/renamed.csv"], ["did you mean 'panda_joint3'"]),
    (["predict", "--robot", "panda", "--model", "D/model", "--data", "D/nan.csv"], ["nan.csv", "panda_joint3"]),
    (["predict", "--model", "D/model", "--data", "D/good.npz"], ["--robot is required"]),
    # payload, drive-gains, monitor, estimate-force: frames and logs
    (["payload", "--robot", "panda", "--model", "D/model", "--data", "D/good.npz", "--frame", "panda_hnd"], ["did you mean 'panda_hand'"]),
    (["payload", "--robot", "panda", "--model", "D/model", "--data", "D/ms.csv", "--frame", "panda_hand"],
     ["ms.csv", "set time unit ms"]),  # payload has no --time-unit: said in words, not as a flag it lacks
    (["drive-gains", *PANDA, "--unloaded", "D/good.csv", "--loaded", "D/good.csv", "--payload-mass", "1", "--frame", "panda_hnd"],
     ["did you mean 'panda_hand'"]),
    (["drive-gains", *PANDA, "--unloaded", "D/good.csv", "--loaded", "D/missing.csv", "--payload-mass", "1", "--frame", "panda_hand"],
     ["missing.csv"]),
    (["monitor", "--robot", "panda", "--model", "D/model", "--data", "D/good.npz", "--frame", "panda_hnd"], ["did you mean 'panda_hand'"]),
    (["monitor", "--robot", "panda", "--model", "D/model", "--data", "D/nan.csv"], ["nan.csv", "panda_joint3"]),
    (["monitor", "--robot", "panda", "--model", "D/model", "--data", "D/good.npz", "--quiet", "9:x"], ["--quiet"]),
    (["estimate-force", "--robot", "panda", "--model", "D/model", "--data", "D/good.npz", "--frame", "panda_hnd"],
     ["did you mean 'panda_hand'"]),
    (["estimate-force", "--robot", "panda", "--model", "D/model", "--data", "D/deg.csv", "--frame", "panda_hand"],
     ["--angle-unit deg"]),
    # excite, friction, frames
    (["excite", "--robot", "pandaa"], ["did you mean 'panda'?"]),
    (["excite", *PANDA, "--rate", "1"], ["--rate", "twice the highest harmonic"]),
    (["excite", "--robot", "panda", "--lock", "panda_finger"], ["did you mean 'panda_finger_joint"]),
    (["friction", "--data", "D/nohdr.csv"], ["no header row", "--columns 'q=0:7;v=7:14;tau=14:21'"]),
    (["friction", "--data", "D/good.csv", "--joints", "panda_joint1", "--columns", "q=pos_{joint}"], ["pos_panda_joint1", "did you mean"]),
    (["friction", "--data", "D/ms.csv", "--joints", "panda_joint1"], ["--time-unit ms"]),
    (["frames", "--robot", "pandaa"], ["did you mean 'panda'?"]),
    (["frames", "--robot", "panda", "--add-frame", "x:panda_lnk8:0,0,0.1"], ["did you mean 'panda_link8'"]),
]
_NEEDS_OUT = {"identify": "run", "predict": "p.npz", "payload": "p.json", "drive-gains": "g.json", "monitor": "mon",
              "estimate-force": "f.npz", "excite": "ex", "friction": "fr"}
_KWARG = re.compile(r"(?<![\w.\-\[])([a-z][a-z0-9]*_[a-z0-9_]+|rate|prior|columns|gains|trim|mode|flags|robot|method|gamma|"
                    r"weights|outliers|resample|velocity|accept|force|ellipsoids|regularization|quiet|state|align)\s*=(?!=)")
_CLAIMED = [re.compile(r"\b(?:drop|remove|omit|without|leave out|leave|instead of)\s+(--[a-z][\w-]*)"),
            re.compile(r"(--[a-z][\w-]*)\s+(?:was|were|is)\s+(?:given|passed)")]


def _options(command: str) -> set[str]:
    cmd = get_command(app).commands[command]
    return {o for p in cmd.params for o in [*p.opts, *getattr(p, "secondary_opts", [])]}


def language_problems(text: str, argv: list[str], command: str) -> list[str]:
    """What is wrong with the wording of one failed command line (empty: nothing)."""
    problems = []
    lines = [ln for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:")]
    if len(errors) != 1 or len(lines) > 3 or "Traceback" in text:
        problems.append(f"not one error line: {lines}")
    if "=[" in text:
        problems.append("'=[' (a Python list argument)")
    if re.search(r"\bpass\s+[A-Za-z_]\w*\s*=", text):
        problems.append("'pass x=' (Python keyword advice)")
    unquoted = re.sub(r"'[^']*'", "''", text)
    if m := _KWARG.search(unquoted):
        problems.append(f"Python keyword argument {m.group(0)!r}")
    if m := re.search(r"`[A-Za-z_]\w*(=[^`]*)?`", text):
        problems.append(f"unrendered setting {m.group(0)}")
    given = {a.split("=")[0] for a in argv if a.startswith("--")}
    for rx in _CLAIMED:
        problems += [f"says to drop {f}, which was not given" for f in rx.findall(text) if f not in given]
    known = _options(command)
    outside_examples = re.sub(r"`[^`]*`", "", unquoted)
    problems += [f"{f}: no such option of {command}" for f in set(re.findall(r"(?<![\w-])--[a-z][\w-]*", outside_examples))
                 if f not in known]
    return problems


@pytest.mark.parametrize("argv, needles", CASES, ids=[f"{i:02d}-{c[0][0]}" for i, c in enumerate(CASES)])
def test_bad_command_line_is_one_line_in_its_own_flags(logs, tmp_path, argv, needles):
    d, _ = logs
    args = [a.replace("D/", f"{d}/") for a in argv]
    out = tmp_path / _NEEDS_OUT[argv[0]] if argv[0] in _NEEDS_OUT else None
    r = _run([*args, *(["--out", out] if out else [])])
    text = r.output
    assert r.exit_code == 2, text
    assert language_problems(text, args, argv[0]) == [], text
    flat = " ".join(text.split())
    for n in needles:
        assert n in flat, f"{n!r} not in {flat}"
    assert out is None or not out.exists()


def test_the_table_covers_the_commands_and_is_broad():
    assert len(CASES) >= 40
    assert {c[0][0] for c in CASES} >= {"identify", "predict", "payload", "drive-gains", "monitor", "estimate-force",
                                        "excite", "friction", "frames"}


def test_the_checker_catches_python_advice_and_invented_flags():
    """The wording rules fail on the messages the issue quotes (a checker that cannot fail proves nothing)."""
    argv = ["identify", "--robot", "panda"]
    bad = ["error: x.csv: missing joints; pass joint_names=[...]",
           "error: x.csv: say columns={'q': '0:7'} and pass rate=...",
           "error: ellipsoids too small: drop --no-contain-prior",
           "error: give `rate=HZ`",
           "error: x\nTraceback (most recent call last):",
           "error: use --no-such-flag"]
    for text in bad:
        assert language_problems(text, argv, "identify"), text
    assert language_problems("error: x.csv: give --rate HZ or --columns 'q=0:7;v=7:14'", argv, "identify") == []


# ---- the mechanism ---------------------------------------------------------------------------------


def test_python_callers_read_the_field_and_the_cli_the_flag(panda, logs):
    from sensorless import load_robot

    d, tr = logs
    with pytest.raises(JointNameError) as exc:
        load_robot("panda").joint_order(tr.joint_names, "x.npz")
    msg = str(exc.value)
    assert "`lock_joints=['panda_finger_joint1', 'panda_finger_joint2']`" in msg and "--lock" not in msg
    assert exc.value.settings == [("lock_joints", "['panda_finger_joint1', 'panda_finger_joint2']")]
    assert settings_in(f"a {setting('rate', placeholder='HZ')} b {setting('contain_prior', True)}") == [
        ("rate", "HZ"), ("contain_prior", "True")]


def _tiny_app(message: str) -> typer.Typer:
    from sensorless.cli.common import guarded

    tiny = typer.Typer()

    @tiny.command()
    @guarded
    def run(contain_prior: bool = typer.Option(True), rate: float = typer.Option(None),
            lock: list[str] = typer.Option(None),
            floating_base: bool = typer.Option(None, "--floating-base/--fixed-base")) -> None:
        raise SensorlessError(message)

    return tiny


def test_a_flag_is_said_to_be_dropped_only_when_it_was_given():
    msg = (f"use the grown ellipsoids ({setting('contain_prior', True)}), give {setting('rate', placeholder='HZ')}, "
           f"lock {setting('lock_joints', ['a', 'b'])}, set {setting('lowpass', 5.0)}, load it with "
           f"{setting('floating_base', True)}" + python_only("call prepare() first"))
    tiny = _tiny_app(msg)
    given = runner.invoke(tiny, ["--no-contain-prior", "--fixed-base"]).output
    assert "drop --no-contain-prior" in given and "--rate HZ" in given and "--lock a --lock b" in given
    assert "--floating-base instead of --fixed-base" in given  # the default is neither: not "drop"
    assert "lowpass 5.0" in given and "in Python" not in given and "`" not in given  # no such option: in words
    default = runner.invoke(tiny, []).output
    assert "--contain-prior, already in effect" in default and "drop" not in default and "instead" not in default
    assert "load it with --floating-base" in default


def test_library_messages_never_say_pass_keyword():
    """Static scan: no string of the package words advice as 'pass name=' or in two languages at once."""
    bad = []
    for path in SRC.rglob("*.py"):
        tree = ast.parse(path.read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                and n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for n in ast.walk(tree):
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs:
                text = n.value
            elif isinstance(n, ast.JoinedStr):
                text = "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in n.values)
            else:
                continue
            if re.search(r"\bpass [A-Za-z_]\w*=", text) or re.search(r"\((?:library|CLI|command line):|in Python\)", text):
                bad.append(f"{path.relative_to(SRC)}:{n.lineno}: {text[:80]}")
            elif isinstance(n, ast.Constant) and re.search(r"\{(?:setting|python_only|did_you_mean)\(", text):  # not an f-string
                bad.append(f"{path.relative_to(SRC)}:{n.lineno}: {text[:80]}")
    assert bad == []


# ---- --angle-unit deg ---------------------------------------------------------------------------


def test_angle_unit_deg_reads_degrees_and_predict_reuses_it(logs, tmp_path):
    d, _ = logs
    common = ["--method", "ols", "--joint-terms", "fv,fc,offset", "--no-plot"]
    r = _run(["identify", *PANDA, "--data", d / "deg.csv", "--angle-unit", "deg", *common, "--out", tmp_path / "deg"])
    assert r.exit_code == 0, r.output
    r = _run(["identify", *PANDA, "--data", d / "good.csv", *common, "--out", tmp_path / "rad"])
    assert r.exit_code == 0, r.output
    deg, rad = (json.loads((tmp_path / k / "result.json").read_text()) for k in ("deg", "rad"))
    assert deg["settings"]["preprocessing"]["angle_unit"] == "deg" and rad["settings"]["preprocessing"]["angle_unit"] == "rad"
    p_deg, p_rad = (np.array(list(doc["parameters"].values())) for doc in (deg, rad))
    np.testing.assert_allclose(p_deg, p_rad, rtol=1e-6, atol=1e-8)  # the same samples, read in degrees
    r = _run(["predict", "--robot", "panda", "--model", tmp_path / "deg", "--data", d / "deg.csv", "--out", tmp_path / "p.npz"])
    assert r.exit_code == 0, r.output  # the model's angle unit, without --angle-unit
    r = _run(["predict", "--robot", "panda", "--model", tmp_path / "rad", "--data", d / "good.csv", "--out", tmp_path / "q.npz"])
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(np.load(tmp_path / "p.npz")["tau_pred"], np.load(tmp_path / "q.npz")["tau_pred"], rtol=1e-6, atol=1e-8)


def test_degrees_leave_prismatic_joints_alone():
    from sensorless.data import Trajectory
    from sensorless.data.angles import to_radians

    class Robot:  # one revolute, one prismatic joint
        joint_names = ("hinge", "rail")

        def is_revolute(self, name):
            return name == "hinge"

    t = np.arange(5) * 0.01
    q = np.column_stack([np.full(5, 90.0), np.full(5, 0.5)])
    out = to_radians(Trajectory(t=t, q=q, joint_names=("hinge", "rail"), v=q.copy()), "deg", Robot())
    np.testing.assert_allclose(out.q[:, 0], np.pi / 2) and np.testing.assert_allclose(out.q[:, 1], 0.5)
    np.testing.assert_allclose(out.v[:, 1], 0.5)
    assert "rail" in out.units["angles"] and "angles" not in Trajectory(t=t, q=q, joint_names=("hinge", "rail")).units
    with pytest.raises(SensorlessError, match="angle_unit"):
        to_radians(out, "grad")


def test_frame_and_joint_names_get_the_closest_known_ones(solo12):
    """One helper (errors.did_you_mean) for every name lookup: robot frames, the IMU frame, joints."""
    from sensorless.data.imu import imu_frame_base_acceleration
    from sensorless.errors import RobotModelError, did_you_mean

    assert did_you_mean("FL_FOT", ["FL_FOOT", "FR_FOOT", "HL_FOOT"]).startswith("did you mean 'FL_FOOT' or ")
    assert did_you_mean("pandaa", ["PANDA", "ur5"]) == "did you mean 'PANDA'?"  # case-insensitive, the known spelling
    assert did_you_mean("zzz", ["panda", "ur5"]) == ""
    with pytest.raises(RobotModelError, match="no frame 'bse_link' for the IMU; did you mean 'base_link'"):
        imu_frame_base_acceleration(solo12, None, "bse_link", None)
    with pytest.raises(RobotModelError, match=r"unknown frame 'FL_FOT' \(did you mean 'FL_FOOT'"):
        solo12.frame_id("FL_FOT")
    with pytest.raises(RobotModelError, match=r"unknown joint 'FL_KNE' \(did you mean 'FL_KFE'"):
        solo12.joint_id("FL_KNE")

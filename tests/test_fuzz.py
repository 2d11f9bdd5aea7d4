"""Property-based fuzzing (hypothesis): every failure is a SensorlessError, every success is sane.

Readers get random shapes, dtypes, NaN/inf/huge values and truncated or corrupted bytes;
``identify`` gets small random trajectories of a 2-link arm; the CLI gets random option
values. Properties: nothing but :class:`SensorlessError` escapes, and whatever succeeds
holds finite values (readers: |x| ≤ MAX_ABS_VALUE; identify: finite parameters, and either
of sane magnitude or flagged by a warning). Bounded examples keep the file under a minute;
``studies/benchmarks/fuzz.py`` runs the long version (≥ 10,000 inputs).
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

from sensorless.data import Trajectory, read_trajectory  # noqa: E402
from sensorless.data.validation import MAX_ABS_VALUE  # noqa: E402
from sensorless.errors import SensorlessError  # noqa: E402

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
TWO_LINK = (Path(__file__).parent / "data" / "two_link.urdf").read_text()  # also studies/benchmarks/fuzz.py's

_SPECIAL = st.sampled_from([0.0, -0.0, 1.0, np.nan, np.inf, -np.inf, 1e300, -1e300, 1e-300, 1e30, 1e10, 5e-324])
_DTYPES = st.sampled_from(["f8", "f4", "i8", "u1", "bool", "c16", "M8[s]", "U3", "O"])


def _array(draw, n_max=12, cols_max=4):
    dtype = draw(_DTYPES)
    shape = draw(st.sampled_from([(), (0,), (draw(st.integers(0, n_max)),),
                                  (draw(st.integers(0, n_max)), draw(st.integers(0, cols_max))),
                                  (2, 2, 2)]))
    if dtype == "O":
        return np.array([None] * (int(np.prod(shape)) or 1), dtype=object)
    if dtype in ("U3", "M8[s]", "c16", "bool", "u1", "i8"):
        return np.zeros(shape, dtype=dtype)
    base = draw(hnp.arrays(np.float64, shape, elements=st.floats(-10, 10)))
    if base.size and draw(st.booleans()):
        base.flat[draw(st.integers(0, base.size - 1))] = draw(_SPECIAL)
    return base.astype(dtype)


@st.composite
def npz_contents(draw):
    keys = draw(st.lists(st.sampled_from(["times", "positions", "velocities", "accelerations", "torques",
                                          "joint_names", "contact", "imu_acc", "current"]), min_size=1, max_size=6,
                         unique=True))
    return {k: (np.array(draw(st.lists(st.text(max_size=3), max_size=4))) if k == "joint_names" and draw(st.booleans())
                else _array(draw)) for k in keys}


def _check_trajectory(tr: Trajectory) -> None:
    for f in ("t", "q", "v", "a", "tau"):
        val = getattr(tr, f)
        if val is not None:
            assert np.all(np.isfinite(val)), f
            if f != "t":
                assert np.all(np.abs(val) <= MAX_ABS_VALUE), f


def _read(path: Path, **kw) -> None:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tr = read_trajectory(path, **kw)
    except SensorlessError:
        return
    _check_trajectory(tr)


@FUZZ
@given(npz_contents(), st.integers(0, 3), st.integers(0, 10 ** 6))
def test_fuzz_npz_reader(contents, damage, seed):
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "f.npz"
        with open(f, "wb") as fh:
            np.savez_compressed(fh, **contents) if damage == 3 else np.savez(fh, **contents)
        data = bytearray(f.read_bytes())
        rng = np.random.default_rng(seed)
        if damage == 1:
            data = data[: rng.integers(0, len(data))]
        elif damage >= 2 and data:
            idx = rng.integers(0, len(data), size=max(1, len(data) // 50))
            data = bytearray(data)
            for i in idx:
                data[i] = rng.integers(0, 256)
        f.write_bytes(bytes(data))
        _read(f, rate=100.0)


@FUZZ
@given(st.lists(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4),
                                   st.sampled_from(["", "nan", "1e400", "True", "2020-01-01", "1+2j"])),
                         min_size=1, max_size=5), min_size=0, max_size=8),
       st.booleans(), st.integers(0, 10 ** 6))
def test_fuzz_csv_reader(rows, header, seed):
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "f.csv"
        lines = (["t,q_a,q_b,tau_a,tau_b"] if header else []) + [",".join(map(str, r)) for r in rows]
        text = "\n".join(lines)
        if seed % 3 == 0 and text:
            text = text[: seed % len(text)]
        f.write_text(text)
        _read(f, rate=100.0) if header else _read(f, columns={"q": "0:2"}, rate=100.0)


@FUZZ
@given(npz_contents(), st.booleans(), st.integers(0, 10 ** 6))
def test_fuzz_hdf5_reader(contents, corrupt, seed):
    h5py = pytest.importorskip("h5py")
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "f.h5"
        with h5py.File(f, "w") as h:
            for k, v in contents.items():
                if v.dtype.kind in "OU":
                    v = np.char.encode(v.astype(str)) if v.dtype.kind == "U" else np.zeros(1)
                if v.dtype.kind == "M":
                    v = v.astype("i8")
                h[k] = v
        if corrupt:
            data = bytearray(f.read_bytes())
            rng = np.random.default_rng(seed)
            for i in rng.integers(0, len(data), size=max(1, len(data) // 30)):
                data[i] = rng.integers(0, 256)
            f.write_bytes(bytes(data))
        _read(f, rate=100.0)


@pytest.fixture(scope="module")
def two_link(tmp_path_factory):
    from sensorless.robot import load_robot

    f = tmp_path_factory.mktemp("robot") / "two.urdf"
    f.write_text(TWO_LINK)
    return load_robot(f)


def run_identify(robot, traj: Trajectory, method: str) -> str:
    """'typed' | 'ok' | 'flagged'; raises AssertionError on silent garbage, anything else on escape."""
    from sensorless.identification import identify

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = identify(robot, traj, method=method, gamma=1e-3)
    except SensorlessError:
        return "typed"
    assert np.all(np.isfinite(res.parameters)), "non-finite parameters on success"
    sane = np.max(np.abs(res.parameters)) < 1e6
    assert sane or caught, f"huge parameters {np.max(np.abs(res.parameters)):.3g} without a warning"
    return "ok" if sane else "flagged"


@FUZZ
@given(st.integers(3, 400), st.floats(1e-4, 3.0), st.sampled_from(["ols", "wls", "svd", "lmi"]),
       st.integers(0, 10 ** 6), st.sampled_from(["none", "nan", "spike", "const", "still", "huge"]))
def test_fuzz_identify_small_random_trajectories(two_link, n, amp, method, seed, defect):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    w = rng.uniform(0.2, 3.0, size=2)
    q = amp * np.sin(np.outer(t, w) + rng.uniform(0, 6, 2))
    v = amp * w * np.cos(np.outer(t, w))
    a = -amp * w ** 2 * np.sin(np.outer(t, w))
    tau = rng.normal(scale=rng.choice([1e-3, 1.0, 100.0]), size=(n, 2))
    if defect == "nan":
        tau[rng.integers(n), rng.integers(2)] = np.nan
    elif defect == "spike":
        tau[rng.integers(n), rng.integers(2)] = 10.0 ** rng.integers(5, 300)
    elif defect == "const":
        q[:] = 0.3
    elif defect == "still":
        q[:, 1] = 0.1
        v[:, 1] = a[:, 1] = 0.0
    elif defect == "huge":
        tau *= 1e12
    tr = Trajectory(t=t, q=q, v=v, a=a, tau=tau, joint_names=("j1", "j2"))
    run_identify(two_link, tr, method)


OPTION_VALUES = st.sampled_from(["0", "-1", "nan", "inf", "-inf", "1e300", "1e-300", "abc", "", "3", "11", "2.5"])
OPTIONS = ["--rate", "--lowpass", "--savgol-window", "--decimate", "--gamma", "--coulomb-smoothing", "--regularization",
           "--outliers", "--method", "--ellipsoids", "--joint-terms", "--columns"]


@pytest.fixture(scope="module")
def small_log(tmp_path_factory, two_link):
    from sensorless.data import write_npz
    from sensorless.testing import perturbed_truth, synthetic_trajectory
    from sensorless.excitation import random_fourier

    d = tmp_path_factory.mktemp("cli")
    truth = perturbed_truth(two_link, rng=0)
    tr = synthetic_trajectory(truth, random_fourier(two_link, rng=1).sample(100, 4.0), noise_std=0.05, rng=2)
    return d, write_npz(tr, d / "log.npz")


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(st.lists(st.tuples(st.sampled_from(OPTIONS), OPTION_VALUES), min_size=1, max_size=3, unique_by=lambda x: x[0]))
def test_fuzz_cli_option_values(small_log, opts):
    from typer.testing import CliRunner

    from sensorless.cli import app

    d, log = small_log
    robot = d / "two.urdf"
    robot.write_text(TWO_LINK)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "o"
        args = ["identify", "--robot", str(robot), "--data", str(log), "--out", str(out)]
        for k, v in opts:
            args += [k, v]
        r = CliRunner().invoke(app, args)
        assert r.exit_code in (0, 2), r.output  # 1 = typer's usage error is fine too
        if r.exit_code == 2 and "internal error" in r.output:
            pytest.fail(r.output)
        assert "Traceback" not in r.output and "internal error" not in r.output, r.output
        if r.exit_code == 0:
            import json

            doc = json.loads((out / "result.json").read_text())
            vals = np.array(list(doc["parameters"].values()), dtype=float)
            assert np.all(np.isfinite(vals))
        else:
            assert not out.exists()


# ---- issue 26: the fuzz classes of studies/benchmarks/fuzz_classes (run through its fuzz.py) --------
import json  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "studies" / "benchmarks"
sys.path.insert(0, str(BENCH))
from fuzz_classes import common as fc  # noqa: E402
from fuzz_classes.common import BAD  # noqa: E402

def run_fuzz(tmp_path, classes: str, scale: float) -> dict:
    out = tmp_path / "fuzz.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    p = subprocess.run([sys.executable, str(BENCH / "fuzz.py"), "--classes", classes, "--scale", str(scale),
                        "--timeout", "5", "--jobs", "1", "--out", str(out)], capture_output=True, text=True, env=env,
                       timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(out.read_text())


@pytest.mark.parametrize("kind,scale", [("outputs", 0.02), ("descriptions", 0.02), ("oversize", 0.025),
                                        ("model_folder", 0.025), ("containers", 0.025), ("numerics", 0.05),
                                        ("formats", 0.05), ("service", 0.05)])
def test_fuzz_class_has_no_bad_outcome(tmp_path, kind, scale):
    doc = run_fuzz(tmp_path, kind, scale)
    counts = doc["per_kind"][kind]
    assert doc["n_inputs"] >= 10
    assert {k: counts[k] for k in BAD} == {k: 0 for k in BAD}, doc["examples"]


def test_fuzz_driver_writes_every_outcome_and_counts(tmp_path):
    doc = run_fuzz(tmp_path, "outputs", 0.004)
    assert set(doc["totals"]) == set(fc.OUTCOMES) and {"data_loss", "executed", "disclosure"} <= set(doc["totals"])
    assert doc["n_inputs"] + doc["notes"]["outputs"].get("skipped", 0) == 6
    assert doc["per_kind"]["outputs"]["crash"] == 0 and doc["per_kind"]["outputs"]["hang"] == 0


def _fake_loader(monkeypatch, effect):
    import sensorless.robot
    from sensorless.errors import RobotModelError

    def load_robot(path, **kw):
        effect(Path(path))
        raise RobotModelError(f"{path}: fake failure")

    monkeypatch.setattr(sensorless.robot, "load_robot", load_robot)


def test_harness_classifies_a_written_marker_as_executed(tmp_path, monkeypatch):
    from fuzz_classes import descriptions

    ctx = descriptions.setup(tmp_path, 0.01)
    _fake_loader(monkeypatch, lambda p: (p.parent / "EXECUTED").write_text("ran"))
    assert descriptions.case(np.random.default_rng(0), tmp_path, ctx)[0] == "executed"


def test_harness_classifies_a_leaked_secret_as_disclosure(tmp_path, monkeypatch):
    from fuzz_classes import descriptions
    from sensorless.errors import RobotModelError

    ctx = descriptions.setup(tmp_path, 0.01)

    def leak(p):
        raise RobotModelError(f"{p}: first line: {ctx['secret'].read_text().splitlines()[0]}")

    _fake_loader(monkeypatch, leak)
    assert descriptions.case(np.random.default_rng(0), tmp_path, ctx)[0] == "disclosure"
    _fake_loader(monkeypatch, lambda p: None)  # the same case without the leak is a typed error
    import shutil

    shutil.rmtree(tmp_path / "case")
    assert descriptions.case(np.random.default_rng(0), tmp_path, ctx)[0] == "typed"


def test_harness_classifies_a_deleted_output_as_data_loss(tmp_path, monkeypatch):
    import contextlib
    import shutil

    import sensorless.io
    from fuzz_classes import outputs

    real = sensorless.io.atomic_output_dir

    @contextlib.contextmanager
    def losing(out, force=False, **kw):  # a replacement that loses a previous output (and writes elsewhere)
        if not (Path(out) / fc.MANIFEST).exists():
            with real(out, force=force, **kw) as tmp:
                yield tmp
            return
        shutil.rmtree(out)
        with real(Path(out).parent / "elsewhere", force=True, **kw) as tmp:
            yield tmp

    monkeypatch.setattr(outputs, "TARGETS", ["output"])
    ctx = {"full": None, "ro": None, "mounted": []}
    assert outputs.inprocess_case(np.random.default_rng(1), tmp_path, ctx)[0] in ("ok", "typed")
    shutil.rmtree(tmp_path / "case")
    monkeypatch.setattr(sensorless.io, "atomic_output_dir", losing)
    assert outputs.inprocess_case(np.random.default_rng(1), tmp_path, ctx)[0] == "data_loss"


def test_harness_snapshots_see_a_fifo_replaced_by_a_file(tmp_path):
    f = tmp_path / "pipe"
    os.mkfifo(f)
    before = fc.digest(f)
    f.unlink()
    f.write_text("")
    assert before == "fifo" and fc.digest(f) != before
    out = tmp_path / "o"
    out.mkdir()
    (out / fc.MANIFEST).write_text(json.dumps({"files": ["a.txt"]}))
    assert not fc.complete_output(out)
    (out / "a.txt").write_text("x")
    assert fc.complete_output(out)

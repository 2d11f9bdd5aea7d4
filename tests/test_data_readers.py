"""Issue #27 "Formats": one simulated UR5 log written as an NPZ with `dq`/`ddq` names, as a
MATLAB v7.3 file (MATLAB's column-major layout, cellstr joint names, a struct, one matrix
stored channels × samples) and as a folder of per-signal whitespace `.dat` files with a 1 kHz
controller-tick column reads back to the same Trajectory, and `sensorless identify` gives the
same parameters on each."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from matlab_writer import CellStr, write_mat73
from sensorless.cli import app
from sensorless.data import read_trajectory
from sensorless.errors import DataWarning, UnitsError

RATE = 1000  # Hz: the controller's tick rate
TICK0 = 250_000  # the controller had been running before the log started


@pytest.fixture(scope="module")
def sim(ur5):
    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth, synthetic_trajectory

    motion = random_fourier(ur5, rng=2).sample(RATE, 4.0)
    tr = synthetic_trajectory(perturbed_truth(ur5, rng=1), motion, noise_std=0.05, rng=3)
    ticks = TICK0 + np.arange(len(tr))
    return tr.with_(t=ticks / RATE), ticks


def _npz(tr, path, extra=True):
    arrays = {"time": tr.t, "q": tr.q, "dq": tr.v, "ddq": tr.a, "tau": tr.tau,
              "joint_names": np.array(tr.joint_names)}
    if extra:
        arrays["motor_temp"] = np.full_like(tr.q, 40.0)  # a signal no field uses
    np.savez(path, **arrays)
    return path


def _mat73(tr, path):
    """MATLAB: log.t (N × 1), log.q / log.dq / log.ddq (N × n), tau saved as n × N (one row per
    joint), joint names a cellstr."""
    return write_mat73(path, {"log": {"t": tr.t[:, None], "q": tr.q, "dq": tr.v, "ddq": tr.a},
                              "tau": tr.tau.T.copy(), "joint_names": CellStr(tr.joint_names)})


def _dat_folder(tr, ticks, folder):
    folder.mkdir()
    header = "tick " + " ".join(tr.joint_names)
    for name, val in (("q", tr.q), ("dq", tr.v), ("ddq", tr.a), ("tau", tr.tau)):
        rows = np.column_stack([ticks, val])
        np.savetxt(folder / f"{name}.dat", rows, fmt=["%d"] + ["%.17g"] * val.shape[1], header=header, comments="")
    return folder


@pytest.fixture(scope="module")
def files(sim, tmp_path_factory):
    tr, ticks = sim
    d = tmp_path_factory.mktemp("formats")
    return {"npz": _npz(tr, d / "run.npz"), "mat": _mat73(tr, d / "run.mat"),
            "dat": _dat_folder(tr, ticks, d / "run")}


def _read(path, ur5, **kw):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return read_trajectory(path, robot=ur5, **kw)


def test_npz_mat73_and_per_signal_dat_read_back_to_the_same_trajectory(sim, files, ur5):
    tr, _ = sim
    logs = {"npz": _read(files["npz"], ur5), "mat": _read(files["mat"], ur5),
            "dat": _read(files["dat"], ur5, time_unit="tick", rate=RATE)}
    for kind, got in logs.items():
        assert got.joint_names == tr.joint_names, kind
        for f in ("t", "q", "v", "a", "tau"):
            np.testing.assert_allclose(getattr(got, f), getattr(tr, f), rtol=0, atol=1e-12, err_msg=f"{kind} {f}")
    assert "converted from ticks at 1000 Hz" in logs["dat"].units["t"]
    assert "tau" in logs["mat"].units["layout"]  # the n × N matrix was transposed, and it says so


def test_identify_gives_the_same_parameters_on_every_format(sim, files, tmp_path):
    run = CliRunner().invoke
    common = ["identify", "--robot", "ur5", "--method", "ols", "--no-plot", "--joint-terms", "fv,fc,offset",
              "--coulomb-smoothing", "0.01"]
    params = {}
    for kind, extra in (("npz", []), ("mat", []), ("dat", ["--time-unit", "tick", "--rate", str(RATE)])):
        out = tmp_path / kind
        r = run(app, [*common, "--data", str(files[kind]), *extra, "--out", str(out)])
        assert r.exit_code == 0, r.output
        doc = json.loads((out / "result.json").read_text())
        params[kind] = doc["parameters"]
        signals = next(iter(doc["settings"]["signals"].values()))
        assert signals["v"] == "logged" and signals["a"] == "logged", signals  # dq/ddq used, not re-derived
    names = list(params["npz"])
    assert len(names) > 40 and all(list(p) == names for p in params.values())
    ref = np.array([params["npz"][k] for k in names])
    for kind in ("mat", "dat"):
        np.testing.assert_allclose([params[kind][k] for k in names], ref, rtol=1e-9, atol=1e-9, err_msg=kind)


def test_npz_dq_ddq_are_used_and_an_unused_array_is_named(sim, files, ur5):
    tr, _ = sim
    with pytest.warns(DataWarning, match=r"arrays not used: 'motor_temp'") as rec:
        got = read_trajectory(files["npz"], robot=ur5)
    assert len([w for w in rec if "not used" in str(w.message)]) == 1  # one warning per file
    with np.load(files["npz"]) as z:
        assert np.array_equal(got.v, z["dq"]) and np.array_equal(got.a, z["ddq"])


def test_tick_column_without_a_unit_is_refused_naming_the_column_and_the_flag(files, ur5, tmp_path):
    with pytest.raises(UnitsError, match=r"time column 'tick'.*`time_unit='tick'` `rate=HZ`"):
        _read(files["dat"], ur5)
    r = CliRunner().invoke(app, ["identify", "--robot", "ur5", "--data", str(files["dat"]), "--method", "ols",
                                 "--out", str(tmp_path / "m")])
    assert r.exit_code == 2 and "'tick'" in r.output and "--time-unit tick --rate HZ" in r.output
    assert not (tmp_path / "m").exists()
